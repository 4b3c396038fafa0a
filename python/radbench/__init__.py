"""radbench from Python: its processing pipeline, its files and its simulated bench.

Everything here calls radbench's own Rust code (the same as the ``radbench`` command line), so
the numbers are radbench's:

- :func:`read_capture` reads a capture folder (or ``.sigmf-meta``, or an I and Q ``.trc``
  pair): I/Q as numpy arrays (raw at the capture rate, and decimated), metadata, ground truth;
- :func:`read_run` reads a campaign run folder: manifest, steps, ``results.json``;
- :func:`process` runs ``radbench process``'s pipeline on a capture or on samples and returns
  what its ``summary.json`` holds, with the profiles as numpy arrays;
- :func:`captures` lists the captures ``radbench process`` would process in an archive;
- :func:`catalog` opens the run catalog (``runs/catalog.sqlite``) and queries its runs and
  captures (plain :mod:`sqlite3` over its documented schema);
- :mod:`radbench.waveform` makes the transmitted waveforms and their AWG codes;
- :class:`Bench` drives a bench (a bench file, or the built-in mock lab) as ``radbench capture``
  does, warm: connected once, the waveform and the pipeline kept between captures;
- :class:`MockLab` runs the simulated bench in-process on 127.0.0.1 for pyvisa scripts (and
  the ``mock_lab`` pytest fixture gives one to a test).

Errors are :class:`radbench.errors.RadbenchError` (``InputError`` is also a ``ValueError``)
carrying radbench's message. Long calls release the GIL, so threads (and Dask) run in parallel.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from . import _radbench
from . import waveform
from .errors import InputError, InstrumentError, ProcessingError, RadbenchError
from ._lab import MockLab
from ._catalog import Catalog, catalog

if sys.version_info >= (3, 11):
    import tomllib as _toml
else:  # pragma: no cover - Python 3.9 and 3.10
    import tomli as _toml

__all__ = [
    "Bench",
    "Capture",
    "Catalog",
    "InputError",
    "InstrumentError",
    "MockLab",
    "Processed",
    "ProcessingError",
    "Profile",
    "RadbenchError",
    "Run",
    "Step",
    "captures",
    "catalog",
    "process",
    "read_capture",
    "read_run",
    "waveform",
]

__version__: str = _radbench.__version__

PathLike = Union[str, "os.PathLike[str]"]


def _files(capture: Any) -> List[str]:
    """The file list of a capture given as a path, a pair of ``.trc`` paths or a Capture."""
    if isinstance(capture, Capture):
        # A SigMF recording is named by its .sigmf-meta; a .trc pair by both files.
        sigmf = [f for f in capture.files if f.endswith(".sigmf-meta")]
        return sigmf or list(capture.files)
    if isinstance(capture, (str, os.PathLike)):
        return [os.fspath(capture)]
    if isinstance(capture, (list, tuple)) and all(isinstance(c, (str, os.PathLike)) for c in capture):
        return [os.fspath(c) for c in capture]
    raise InputError(
        f"capture: {type(capture).__name__}; give a capture folder, a .sigmf-meta, an (I, Q) pair "
        "of .trc paths, a Capture, or a 1-D complex numpy array of samples"
    )


def _stack(arrays: List[np.ndarray]) -> Union[np.ndarray, List[np.ndarray]]:
    """One 2-D array (repetition, sample) when the repetitions are equally long, else the list.
    A single repetition is reshaped, not copied."""
    if len(arrays) == 1:
        return arrays[0].reshape(1, -1)
    if arrays and all(a.shape == arrays[0].shape for a in arrays):
        return np.stack(arrays)
    return arrays


@dataclass
class Capture:
    """A saved capture, as :func:`read_capture` reads it.

    ``iq``: complex128 volts at the capture rate, shape ``(repetitions, samples)``, each
    repetition from the first sample after the marker. ``decimated``: each repetition decimated
    to the processing rate and aligned to the marker as radbench's pipeline does (``None`` when
    the capture does not say its waveform; ``not_decimated`` says why). ``metadata``: the SigMF
    metadata as a dict (``{}`` for a ``.trc`` pair); ``radbench``: its ``radbench:`` fields;
    ``scene``: the simulated scene (ground truth) of a simulated bench's capture, else ``None``.
    """

    path: str
    files: List[str]
    iq: Union[np.ndarray, List[np.ndarray]]
    capture_rate_hz: float
    iq_t0_s: np.ndarray
    decimated: Optional[Union[np.ndarray, List[np.ndarray]]]
    processing_rate_hz: Optional[float]
    decimated_t0_s: np.ndarray
    metadata: Dict[str, Any]
    radbench: Dict[str, Any]
    scene: Optional[Dict[str, Any]]
    not_decimated: Optional[str] = None

    @property
    def repetitions(self) -> int:
        return len(self.iq)

    @property
    def true_ranges_m(self) -> List[float]:
        """The simulated targets' ranges (ground truth), ``[]`` when not simulated."""
        return [t["range_m"] for t in (self.scene or {}).get("targets", [])]


def read_capture(path: Union[PathLike, Sequence[PathLike]]) -> Capture:
    """Reads a capture: a capture folder, its ``.sigmf-meta``, or ``(i_trc, q_trc)``.

    Raises :class:`InputError` for anything that is not one capture (a run folder holds
    several: use :func:`read_run`)."""
    files = _files(path)
    d = _radbench.read_capture(files)
    metadata: Dict[str, Any] = {}
    meta = next((f for f in d["files"] if str(f).endswith(".sigmf-meta")), None)
    if meta is not None:
        with open(meta, encoding="utf-8") as f:
            metadata = json.load(f)
    decimated = _stack(d["decimated"]) if d["decimated"] else None
    return Capture(
        path=files[0],
        files=[os.fspath(f) for f in d["files"]],
        iq=_stack(d["raw"]),
        capture_rate_hz=d["capture_rate_hz"],
        iq_t0_s=d["raw_t0_s"],
        decimated=decimated,
        processing_rate_hz=d["processing_rate_hz"],
        decimated_t0_s=d["decimated_t0_s"],
        metadata=metadata,
        radbench=json.loads(d["radbench_json"]),
        scene=json.loads(d["scene_json"]) if d["scene_json"] else None,
        not_decimated=d["not_decimated"],
    )


@dataclass
class Profile:
    """One range profile: ``range_m`` (metres) and ``amplitude`` (relative to a unit-gain path
    from AWG output to scope input, or MUSIC's pseudo-spectrum), ``db`` = 20 log10 amplitude."""

    label: str
    range_m: np.ndarray
    amplitude: np.ndarray

    @property
    def db(self) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(self.amplitude)


@dataclass
class Processed:
    """One capture processed. ``summary`` is what ``radbench process`` writes to
    ``summary.json`` (all its keys but ``files``); the attributes below are read from it, and
    the arrays behind it are added: ``profiles`` (the first is the primary one; MUSIC adds its
    Fourier overlay), ``threshold`` (the detection threshold per cell of the primary profile,
    same scale as its amplitude; empty for root-MUSIC and ESPRIT), ``residual`` (what CLEAN
    left), ``complex_profile``, ``aligned`` (the record processed, at the processing rate)."""

    summary: Dict[str, Any]
    options: Dict[str, Any]
    profiles: List[Profile]
    threshold: np.ndarray
    residual: np.ndarray
    complex_profile: Optional[np.ndarray]
    aligned: np.ndarray
    noise_db: Optional[float] = None

    @property
    def targets(self) -> List[Dict[str, Any]]:
        return self.summary["targets"]

    @property
    def ranges_m(self) -> List[float]:
        return [t["range_m"] for t in self.targets]

    @property
    def width_3db_cm(self) -> Optional[float]:
        return self.summary.get("width_3db_cm")

    @property
    def sidelobe_db(self) -> Optional[float]:
        return self.summary.get("sidelobe_db")

    @property
    def snr_db(self) -> Optional[float]:
        return self.summary.get("snr_db")

    @property
    def payload(self) -> Optional[Dict[str, Any]]:
        """The decode: ``{"text", "bit_errors", "bits", "ber", "error"}``."""
        return self.summary.get("payload")

    @property
    def warnings(self) -> List[str]:
        return self.summary.get("warnings", [])

    @property
    def algorithm(self) -> str:
        return self.summary["algorithm"]

    @property
    def waveform(self) -> str:
        return self.summary["waveform"]

    @property
    def profile(self) -> Optional[Profile]:
        return self.profiles[0] if self.profiles else None

    def _repr_html_(self) -> str:
        """Jupyter: the profile as inline SVG, the targets as a table."""
        from ._html import processed_html

        return processed_html(self)

    def plot(self, ax: Any = None) -> Any:
        """Draws the profiles (dB over range, targets marked) on ``ax``, or on a new figure's
        axes; needs matplotlib (an optional dependency). Returns the axes."""
        from ._html import plot

        return plot(self, ax)


def _option_text(value: Any) -> str:
    if isinstance(value, float):
        return repr(value)
    return os.fspath(value) if isinstance(value, os.PathLike) else str(value)


def _argv(options: Mapping[str, Any]) -> List[str]:
    """Keyword options as ``radbench process`` options: ``zero_pad=20`` -> ``--zero-pad=20``,
    ``forward_only=True`` -> ``--forward-only``; ``None`` and ``False`` are left out."""
    argv: List[str] = []
    for name, value in options.items():
        if value is None or value is False:
            continue
        flag = "--" + name.replace("_", "-")
        if value is True:
            argv.append(flag)
        else:
            argv.append(f"{flag}={_option_text(value)}")
    return argv


def _json_value(value: Any) -> Any:
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "item"):  # a NumPy scalar
        return value.item()
    raise TypeError(f"{type(value).__name__} is not an option value")


def _keywords(options: Mapping[str, Any]) -> str:
    """Keyword options as the JSON object radbench deserializes them from (``None`` keeps the
    default)."""
    return json.dumps({k: v for k, v in options.items() if v is not None}, default=_json_value)


def _processed(d: Dict[str, Any]) -> Processed:
    return Processed(
        summary=json.loads(d["summary_json"]),
        options=json.loads(d["options_json"]),
        profiles=[Profile(p["label"], p["range_m"], p["amplitude"]) for p in d["profiles"]],
        threshold=d["threshold"],
        residual=d["residual"],
        complex_profile=d["complex_profile"],
        aligned=d["aligned"],
        noise_db=d["noise_db"],
    )


def process(
    capture_or_samples: Any,
    *,
    waveform: Optional[str] = None,
    algorithm: Optional[str] = None,
    capture_rate: Optional[float] = None,
    **options: Any,
) -> Processed:
    """Processes a capture as ``radbench process`` does, nothing written.

    ``capture_or_samples``: a capture folder, ``.sigmf-meta``, ``(i_trc, q_trc)`` pair or
    :class:`Capture`; or a 1-D complex array of samples in volts (then ``waveform`` and
    ``capture_rate`` in Hz are required; the record starts at the marker unless
    ``trigger_offset`` says otherwise). ``waveform``: ``"msk-lfm"`` or ``"ofdm"`` (captures
    radbench did not make); ``algorithm``: ``correlation``, ``fourier``, ``music``,
    ``root-music``, ``esprit``. ``options`` are the processing choices, by the names a campaign's
    ``[processing]`` table uses or the command line's with ``_`` for ``-`` (``m=32`` or
    ``music_m=32``, ``p=2``, ``zero_pad=20``, ``window="hann"``, ``detector="os-cfar"``,
    ``pfa=1e-4``, ``min_range=0.3``, ``correction="rx"``, ``calibration=PATH``, ...; they reach
    radbench as one JSON object, deserialized into the same type the command line and campaigns
    use), and ``radbench process``'s own options (``system_delay=2.5e-9``,
    ``no_background=True``, ``bandwidth=2e9``, ``payload="hello"``, ``seed=3``, ...), with the
    same defaults, checks and messages (``radbench process --help`` lists them), except that a
    message names the keyword (``window``), not the command line's option (``--window``), and an
    unknown keyword gets the nearest one (``windw``: did you mean ``window``?). Options not given keep what the capture
    recorded. Returns :class:`Processed`; its ``options`` holds every option used.
    """
    if waveform is not None:
        waveform = waveform.replace("_", "-")
    keywords = _keywords({"waveform": waveform, "algorithm": algorithm, **options})
    if isinstance(capture_or_samples, np.ndarray):
        samples = np.ascontiguousarray(capture_or_samples, dtype=np.complex128)
        if samples.ndim != 1:
            raise InputError(f"samples: shape {samples.shape}; give one record, a 1-D array")
        if capture_rate is None:
            raise InputError("capture_rate: needed with samples (their sample rate in Hz)")
        return _processed(_radbench.process_samples(samples, float(capture_rate), 0.0, keywords))
    if capture_rate is not None:
        raise InputError("capture_rate: only with samples (a capture says its own rate)")
    return _processed(_radbench.process_capture(_files(capture_or_samples), keywords))


def captures(*inputs: PathLike) -> Dict[str, List[str]]:
    """The captures ``radbench process INPUTS`` would process, in its order: folder name (the
    one ``radbench process`` gives its results) -> the capture's files (give them to
    :func:`process`). A run folder gives every step's capture."""
    return {name: [os.fspath(f) for f in files] for name, files in _radbench.captures([os.fspath(i) for i in inputs])}


@dataclass
class Step:
    """One step of a campaign run: its ``index``, folder, ``capture`` (:class:`Capture`),
    ``summary`` (its ``summary.json``) and ``result`` (its ``result.json``: the step's entry of
    ``results.json``)."""

    index: int
    path: str
    capture: Optional[Capture]
    summary: Optional[Dict[str, Any]]
    result: Optional[Dict[str, Any]]
    plan: Dict[str, Any] = field(default_factory=dict)


@dataclass
class Run:
    """A campaign run folder: ``manifest`` (``manifest.toml`` as a dict), ``steps`` (every
    planned step; a step not measured yet has no capture), ``results`` (``results.json``, or
    ``None`` for a run that has none yet)."""

    path: str
    manifest: Dict[str, Any]
    steps: List[Step]
    results: Optional[Dict[str, Any]]

    @property
    def status(self) -> str:
        return self.manifest.get("status", "unknown")

    def _repr_html_(self) -> str:
        """Jupyter: the steps as a table (nominal and measured ranges)."""
        from ._html import run_html

        return run_html(self)


#: The reason :func:`read_run` gives a ``running`` manifest that no process works on (as
#: radbench's own readers do, docs/campaign.md "A status that never lies").
STALE_REASON = (
    "the process that ran it stopped without recording its end (a crash, SIGKILL, a power "
    "loss, or a file system that refused the last write): no process holds the run folder's lock"
)


def _lock_is_held(root: Path) -> bool:
    """Whether a process works in the run folder now (holds ``.radbench.lock``)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: cannot tell, believe the manifest
        return True
    try:
        f = open(root / ".radbench.lock", "rb")
    except OSError:
        return False
    with f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return True
        return False


#: The manifest's step journal: while a session runs, one JSON line per step recorded since
#: ``manifest.toml`` was last stored whole (docs/campaign.md, "Long runs").
STEPS_JOURNAL = "manifest-steps.jsonl"


def _merge_steps_journal(root: Path, manifest: Dict[str, Any]) -> None:
    """Merges the run folder's step journal, if any, into ``manifest`` as radbench's own
    readers do: each whole line of the file's last session, while that session has not ended
    (a line cut short, or one that does not read, ends the journal)."""
    try:
        data = (root / STEPS_JOURNAL).read_bytes()
    except FileNotFoundError:
        return
    sessions = manifest.get("sessions") or []
    steps = manifest.get("steps") or []
    if not sessions or "ended" in sessions[-1]:
        return
    lines = data.split(b"\n")[:-1]  # the last piece has no newline: not whole
    for raw in lines:
        try:
            line = json.loads(raw)
            index = int(line["step"]["index"])
            ok = line["session"] == len(sessions) and line["step"]["status"] == "done"
        except (ValueError, KeyError, TypeError):
            break
        if not ok or not 1 <= index <= len(steps):
            break
        steps[index - 1] = line["step"]
        retries = manifest.setdefault("retries", [])
        for r in line.get("retries", []):
            if r not in retries:
                retries.append(r)
        manifest["updated"] = line["updated"]
        sessions[-1]["timing"] = line["timing"]


def _json_file(path: Path) -> Optional[Dict[str, Any]]:
    if not path.is_file():
        return None
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def read_run(path: PathLike, *, captures: bool = True) -> Run:
    """Reads a campaign run folder (``radbench campaign run`` wrote it). ``captures=False``
    skips reading the steps' I/Q (manifest, summaries and results only)."""
    root = Path(path)
    manifest_path = root / "manifest.toml"
    if not manifest_path.is_file():
        raise InputError(f"{root}: not a campaign run folder (no manifest.toml)")
    try:
        with open(manifest_path, "rb") as f:
            manifest = _toml.load(f)
    except (OSError, ValueError) as e:
        raise InputError(f"{manifest_path}: {e}") from e
    _merge_steps_journal(root, manifest)
    if manifest.get("status") == "running" and not _lock_is_held(root):
        manifest["status"] = "interrupted"
        manifest.setdefault("reason", STALE_REASON)
    steps = []
    for planned in manifest.get("plan", {}).get("steps", []):
        index = int(planned["index"])
        folder = root / f"step-{index:03d}"
        meta = folder / "capture.sigmf-meta"
        steps.append(
            Step(
                index=index,
                path=str(folder),
                capture=read_capture(folder) if captures and meta.is_file() else None,
                summary=_json_file(folder / "summary.json"),
                result=_json_file(folder / "result.json"),
                plan=planned,
            )
        )
    return Run(
        path=str(root),
        manifest=manifest,
        steps=steps,
        results=_json_file(root / "results.json"),
    )


from ._bench import Bench  # noqa: E402  (it uses the helpers above)
