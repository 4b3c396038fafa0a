"""A warm session on a bench: :class:`Bench`, what ``radbench capture`` does, from Python, at the
speed of a campaign step (connections, uploaded waveform and pipeline kept between captures)."""

from __future__ import annotations

import atexit
import json
import os
import tempfile
import weakref
from typing import TYPE_CHECKING, Any, Callable, Dict, Optional, Union

from . import _radbench
from ._lab import MockLab, SceneLike
from .errors import InputError, RadbenchError

if TYPE_CHECKING:
    from . import Processed, Run

PathLike = Union[str, "os.PathLike[str]"]

#: Every open session, closed (the bench put in its safe state) when the interpreter exits.
_OPEN: "weakref.WeakSet[Bench]" = weakref.WeakSet()


@atexit.register
def _close_all() -> None:
    for bench in list(_OPEN):
        try:
            bench.close()
        except Exception:  # pragma: no cover - the interpreter is ending
            pass


def _scene_keywords(scene: SceneLike) -> Dict[str, Any]:
    if scene is None:
        return {}
    if isinstance(scene, dict):
        return {"scene_json": json.dumps(scene)}
    if isinstance(scene, (str, os.PathLike)):
        path = os.fspath(scene)
        try:
            with open(path, encoding="utf-8") as f:
                return {"scene_toml": f.read(), "origin": path}
        except OSError as e:
            raise InputError(f"scene: cannot read scene file {path}: {e}") from e
    raise InputError(f"scene: {type(scene).__name__}; give a scene file (TOML) path or a dict")


class Bench:
    """A session on a bench, as ``radbench capture`` uses one, kept open between captures.

    ``bench``: a bench file; ``None`` starts the built-in mock lab (as the command line does
    without ``--bench``; ``scene``, a scene file or dict, and ``scope_model`` choose it); or a
    running :class:`MockLab` (its bench file, calibrated with the lab's exact delay). RF is
    switched on only with ``allow_rf=True``. A bench file with manual front ends
    (``driver = "manual"``) also needs ``manual_front_ends_confirmed=True``: the operator has set
    them by hand (what the command line's typed ``yes`` says); without it a capture is refused
    with :class:`InputError` before anything is switched on. ``trace_io``: a file that journals every exchange
    with the instruments (``--trace-io``).

    Use it as a context manager::

        with radbench.Bench("bench.toml", allow_rf=True) as b:
            p = b.capture()
            print(p.ranges_m)

    ``close()``, leaving the ``with`` block, garbage collection and the interpreter's exit put
    the bench in its safe state (Tx off, AWG outputs off and stopped) and release the
    instruments. One session at a time per bench: a second one on the same instruments raises
    :class:`InstrumentError` saying so. Ctrl-C (a notebook's interrupt) during a call puts the
    bench in its safe state before the ``KeyboardInterrupt`` reaches you.
    """

    def __init__(
        self,
        bench: Union[None, PathLike, MockLab] = None,
        *,
        scene: SceneLike = None,
        allow_rf: bool = False,
        scope_model: Optional[str] = None,
        trace_io: Optional[PathLike] = None,
        manual_front_ends_confirmed: bool = False,
    ) -> None:
        self._session: Optional[Any] = None
        self._bench_file: Optional[str] = None
        self._lab: Optional[MockLab] = None
        path: Optional[str] = None
        if isinstance(bench, MockLab):
            if scene is not None or scope_model is not None:
                raise InputError("scene, scope_model: a MockLab has its own; change its scene with lab.set_scene()")
            self._lab = bench.start()
            fd, path = tempfile.mkstemp(prefix="radbench-bench-", suffix=".toml")
            os.close(fd)
            bench.bench_toml(path, calibrated=True)
            self._bench_file = path
        elif bench is not None:
            if not isinstance(bench, (str, os.PathLike)):
                raise InputError(f"bench: {type(bench).__name__}; give a bench file, a MockLab or None")
            path = os.fspath(bench)
        try:
            self._session = _radbench.Session(
                bench=path,
                allow_rf=bool(allow_rf),
                scope_model=scope_model,
                trace_io=os.fspath(trace_io) if trace_io is not None else None,
                manual_front_ends_confirmed=bool(manual_front_ends_confirmed),
                **_scene_keywords(scene),
            )
        except BaseException:
            self._remove_bench_file()
            raise
        _OPEN.add(self)

    # -- life cycle -----------------------------------------------------------------------
    def __enter__(self) -> "Bench":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

    def close(self) -> Optional[str]:
        """Puts the bench in its safe state and releases the instruments (and the bench's
        lock). Returns the safe state's report; closing again does nothing."""
        session, self._session = self._session, None
        try:
            return session.close() if session is not None else None
        finally:
            self._remove_bench_file()
            _OPEN.discard(self)

    def _remove_bench_file(self) -> None:
        path, self._bench_file = self._bench_file, None
        if path is not None:
            try:
                os.remove(path)
            except OSError:
                pass

    @property
    def closed(self) -> bool:
        return self._session is None

    def _open(self) -> Any:
        if self._session is None:
            raise RadbenchError("the bench session is closed: open a new radbench.Bench")
        return self._session

    def __repr__(self) -> str:
        if self._session is None:
            return "<radbench.Bench (closed)>"
        return f"<radbench.Bench on {self._session.describe()}>"

    # -- measurements ---------------------------------------------------------------------
    def capture(
        self,
        waveform: str = "msk-lfm",
        *,
        algorithm: Optional[str] = None,
        correction: Optional[str] = None,
        repetitions: Optional[int] = None,
        out: Optional[PathLike] = None,
        **processing: Any,
    ) -> "Processed":
        """One measurement, as ``radbench capture`` takes it, warm: the connections, the
        uploaded waveform and the pipeline are kept while the waveform and the options do not
        change.

        ``processing``: the processing choices by the names :func:`radbench.process` takes
        (``window="hann"``, ``m=32``, ``min_range=0.3``, ``calibration=PATH``, ...) and
        ``radbench capture``'s own options (``bandwidth``, ``pulse_us``, ``payload``, ``seed``,
        ``tx_off``, ``wait``, ``background``, ``force``), with its defaults, checks and
        messages. ``out=None`` writes nothing; a folder gets what ``radbench capture --out``
        writes. Returns :class:`radbench.Processed` (its ``summary`` is the capture's
        ``summary.json``)."""
        from . import _keywords, _processed

        if not isinstance(waveform, str):
            raise InputError(f"waveform: {waveform!r}; msk-lfm or ofdm")
        keywords = _keywords({"algorithm": algorithm, "correction": correction, **processing})
        if repetitions is None:
            repetitions = 1
        if isinstance(repetitions, bool) or not isinstance(repetitions, int) or repetitions < 1:
            raise InputError(f"repetitions: {repetitions!r}; a whole number, 1 or more")
        d = self._open().capture(
            waveform.replace("_", "-"), keywords, repetitions, os.fspath(out) if out is not None else None
        )
        return _processed(d)

    def calibrate(self, reference_range: float, *, search: float = 2.0) -> Dict[str, Any]:
        """``radbench calibrate --reference-range R``: the bench's system delay measured on a
        reference target ``reference_range`` metres away, stored in the bench file's
        ``[calibration]`` (the built-in mock lab's is only returned); later captures of this
        session use it. Returns ``{"system_delay_s", "reference_range_m", "measured_range_m",
        "stored_in"}``."""
        return json.loads(self._open().calibrate(float(reference_range), float(search)))

    def calibrate_response(
        self,
        reference_range: float,
        waveform: str = "msk-lfm",
        *,
        repetitions: int = 16,
        gate_ns: Optional[float] = None,
        reflector: Optional[float] = None,
        out: Optional[PathLike] = None,
        force: bool = False,
        **waveform_options: Any,
    ) -> Dict[str, Any]:
        """``radbench calibrate response --reference-range R``: the chain's response measured
        on the reference pillar ``reference_range`` metres away (the bench's system delay
        calibrated first: :meth:`calibrate`), with ``waveform`` and its options
        (``bandwidth``, ``pulse_us``, ``band``, ...: calibrate with what the captures will use).

        It is checked to help (correcting the reference must bring it closer to a flat chain's
        side-lobe and width; ``force=True`` stores it anyway) and stored: at ``out`` (a
        ``.toml`` header, the table beside it), else beside the bench file as
        ``<bench>-response.toml``, named in its ``[calibration]`` so this session's later
        captures correct with it; the built-in mock lab's is not stored without ``out``.
        ``reflector``: a fixed reflector standing in the reference's scene (metres, at least
        0.3 from the reference), measured as the scene's rather than taken for the chain's
        response (``--reflector``). Returns ``radbench calibrate response --json``'s object (``figures``, ``reference``,
        ``chain_echoes``, ``stored_in``, ...); a refused one raises
        :class:`radbench.errors.InputError` with the reason."""
        from . import _keywords

        if not isinstance(waveform, str):
            raise InputError(f"waveform: {waveform!r}; msk-lfm or ofdm")
        if isinstance(repetitions, bool) or not isinstance(repetitions, int) or repetitions < 1:
            raise InputError(f"repetitions: {repetitions!r}; a whole number, 1 or more")
        found = self._open().calibrate_response(
            float(reference_range),
            waveform.replace("_", "-"),
            _keywords(waveform_options),
            repetitions,
            None if gate_ns is None else float(gate_ns),
            None if reflector is None else float(reflector),
            os.fspath(out) if out is not None else None,
            bool(force),
        )
        return json.loads(found)

    def campaign(
        self,
        spec: Union[PathLike, Dict[str, Any]],
        *,
        out: Optional[PathLike] = None,
        retries: Optional[int] = None,
    ) -> "Campaign":
        """A campaign on this bench (``radbench campaign run SPEC --bench FILE``; the built-in
        mock lab the spec describes when the session has no bench file). ``spec``: a spec file
        or the spec as a dict (the TOML file's tables as dicts); ``out``: the run folder
        (default ``runs/<UTC time>-<name>``). Nothing runs until :meth:`Campaign.run`."""
        return Campaign(self, spec, out=out, retries=retries)

    def doctor(self) -> Dict[str, Any]:
        """``radbench doctor --json``: every check of the bench that needs no RF, as data
        (``{"bench", "ok", "checks": [{"id", "status", "detail", "fix"}]}``)."""
        return json.loads(self._open().doctor())



class Campaign:
    """A campaign of a :class:`Bench` session (:meth:`Bench.campaign`).

    :meth:`run` measures it into its run folder and returns the :class:`radbench.Run` that
    :func:`radbench.read_run` gives; ``on_step`` is called with each step as it lands (from
    the thread that called ``run``, for a live plot): a dict with ``index``, ``of``, ``dir``,
    ``skipped`` and ``result`` (the step's entry of ``results.json``). An exception raised in
    ``on_step`` stops the run as Ctrl-C does (the bench put in its safe state, the run folder
    left resumable) and is then raised; :meth:`resume` measures what is missing.
    """

    def __init__(self, bench: Bench, spec: Union[PathLike, Dict[str, Any]], *,
                 out: Optional[PathLike] = None, retries: Optional[int] = None) -> None:
        if isinstance(spec, dict):
            self._spec: Dict[str, Any] = {"spec_json": json.dumps(spec)}
        elif isinstance(spec, (str, os.PathLike)):
            self._spec = {"spec": os.fspath(spec)}
        else:
            raise InputError(f"spec: {type(spec).__name__}; give a campaign spec file or a dict")
        self._bench = bench
        self._retries = retries
        #: The run folder, once the run has started.
        self.dir: Optional[str] = os.fspath(out) if out is not None else None

    def _events(self, on_step: Optional[Callable[[Dict[str, Any]], Any]]) -> Callable[[str], None]:
        def on_event(text: str) -> None:
            event = json.loads(text)
            if event.get("event") == "start":
                self.dir = os.fspath(event["dir"])
            elif on_step is not None:
                on_step(event)

        return on_event

    def run(self, on_step: Optional[Callable[[Dict[str, Any]], Any]] = None) -> "Run":
        """Measures every step (``radbench campaign run``); the run as :func:`read_run`
        reads it."""
        from . import read_run

        if self.dir is not None and os.path.isdir(self.dir) and os.listdir(self.dir):
            raise InputError(
                f"{self.dir} holds a run already: resume() continues it, or give another out"
            )
        dir = self._bench._open().campaign_run(
            self._events(on_step), out=self.dir, retries=self._retries, **self._spec
        )
        return read_run(dir)

    def resume(self, on_step: Optional[Callable[[Dict[str, Any]], Any]] = None) -> "Run":
        """Continues an interrupted run (``radbench campaign resume``): only the steps not
        measured yet."""
        from . import read_run

        if self.dir is None:
            raise InputError("resume: the campaign has not started; run() starts it")
        dir = self._bench._open().campaign_resume(self._events(on_step), self.dir)
        return read_run(dir)
