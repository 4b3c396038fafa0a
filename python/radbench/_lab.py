"""The simulated bench (mock_lab) in-process, for pyvisa scripts and their tests."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Optional, Union

from . import _radbench
from .errors import InputError, RadbenchError

SceneLike = Union[None, str, "os.PathLike[str]", Dict[str, Any]]


def _scene_args(scene: SceneLike) -> Dict[str, Any]:
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


class MockLab:
    """radbench's simulated bench (AWG, scope, Tx and Rx front ends, a scene of targets), started
    in-process on 127.0.0.1 on free ports, speaking the real instruments' protocols.

    Use it as a context manager; everything it started (servers, threads, pseudo-terminals) is
    stopped when the block ends::

        with radbench.MockLab() as lab:
            rm = pyvisa.ResourceManager("@py")
            awg = rm.open_resource(lab.resources["awg"])     # HiSLIP
            scope = rm.open_resource(lab.resources["scope"]) # VXI-11

    ``scene``: a scene file (TOML, as ``radbench mock-lab serve --scene``) or a dict (the scene
    as JSON); default one target at 1 m. ``scope_remote``: the scope's remote interface,
    ``"vxi11"`` (default: what pyvisa-py opens on any port) or ``"vicp"``.
    """

    def __init__(self, scene: SceneLike = None, *, scope_remote: str = "vxi11") -> None:
        self._scene = _scene_args(scene)
        self._scope_remote = scope_remote
        self._lab: Optional[Any] = None

    # -- life cycle -----------------------------------------------------------------------
    def start(self) -> "MockLab":
        """Starts the bench (once every endpoint listens). ``with MockLab() as lab`` calls it."""
        if self._lab is None:
            self._lab = _radbench.Lab(scope_remote=self._scope_remote, **self._scene)
        return self

    def close(self) -> None:
        """Stops every server and thread of the bench (waits for them, at most 10 s)."""
        lab, self._lab = self._lab, None
        if lab is not None:
            lab.close()

    def __enter__(self) -> "MockLab":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

    @property
    def running(self) -> bool:
        return self._lab is not None

    def _running(self) -> Any:
        if self._lab is None:
            raise RadbenchError("the mock lab is not running: use `with MockLab() as lab:` or .start()")
        return self._lab

    # -- where the instruments are ----------------------------------------------------------
    @property
    def endpoints(self) -> List[Dict[str, Any]]:
        """Every endpoint: ``instrument``, ``transport``, ``address``, ``resource``, ``active``."""
        return json.loads(self._running().endpoints_json())

    @property
    def resources(self) -> Dict[str, str]:
        """VISA resource strings pyvisa-py opens: ``awg`` (HiSLIP), ``awg_socket``,
        ``awg_vxi11``, ``scope`` (its active remote interface), ``tx`` and ``rx`` (serial, a
        pseudo-terminal: ``ASRL/dev/pts/N::INSTR``)."""
        found: Dict[str, str] = {}
        names = {("awg", "hislip"): "awg", ("awg", "raw"): "awg_socket", ("awg", "vxi11"): "awg_vxi11",
                 ("tx", "serial"): "tx", ("rx", "serial"): "rx"}
        for e in self.endpoints:
            key = names.get((e["instrument"], e["transport"]))
            if key:
                found[key] = e["resource"]
            elif e["instrument"] == "scope" and e.get("active", True):
                found["scope"] = e["resource"]
        return found

    @property
    def control_address(self) -> str:
        """The scene control channel's ``host:port`` (one JSON object per line)."""
        return self._running().control_address()

    def bench_toml(self, path: Optional[Union[str, "os.PathLike[str]"]] = None, *,
                   calibrated: bool = False) -> str:
        """A radbench bench file for this bench (for ``radbench capture --bench FILE`` while it
        runs); written to ``path`` when given.

        Without ``calibrated`` the file has no ``[calibration]``, as a real bench before
        ``radbench calibrate``: ranges include the lab's fixed system delay (the scene's
        ``system_delay_s``, 2.5 ns by default, 0.375 m) and every output warns that the bench is
        not calibrated. With ``calibrated=True`` it holds the lab's delay as its calibration
        (``[calibration] system_delay_s``, exact: the simulated cables are known), so ranges
        are true ranges at once."""
        text = self._running().bench_toml(self._scope_remote)
        if calibrated:
            delay = float(self.scene["system_delay_s"])
            text += ("\n[calibration]\n# The simulated bench's own system delay (its scene's "
                     "system_delay_s), known exactly.\n"
                     f"system_delay_s = {delay!r}\n")
        if path is not None:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        return text

    # -- the scene ------------------------------------------------------------------------
    def control(self, request: Dict[str, Any]) -> Dict[str, Any]:
        """One request on the control channel (``{"cmd": "get" | "set" | "move" | "add" |
        "remove" | "snr" | "seed" | "last_capture", ...}``); the reply, or :class:`InputError`
        with the lab's reason when it refuses."""
        reply = json.loads(self._running().control(json.dumps(request)))
        if reply.get("ok") is not True:
            raise InputError(f"mock lab: {reply.get('error', 'the lab refused the request')}")
        return reply

    @property
    def scene(self) -> Dict[str, Any]:
        """The scene now."""
        return self.control({"cmd": "get"})["scene"]

    def set_scene(self, scene: Union[str, "os.PathLike[str]", Dict[str, Any]]) -> Dict[str, Any]:
        """Replaces the whole scene (a dict, or a scene file); validated by the lab."""
        if not isinstance(scene, dict):
            from . import _toml

            path = os.fspath(scene)
            try:
                with open(path, "rb") as f:
                    scene = _toml.load(f)
            except (OSError, ValueError) as e:
                raise InputError(f"scene: cannot read scene file {path}: {e}") from e
        return self.control({"cmd": "set", "scene": scene})

    def move(self, target: int, range_m: float) -> Dict[str, Any]:
        """Moves target ``target`` (0 = the first) to ``range_m`` metres."""
        return self.control({"cmd": "move", "target": int(target), "range_m": float(range_m)})

    def add_target(self, range_m: float, amplitude: float = 1.0, **more: Any) -> int:
        """Adds a target; its index."""
        return int(self.control({"cmd": "add", "target": {"range_m": range_m, "amplitude": amplitude, **more}})["index"])

    def remove_target(self, target: int) -> Dict[str, Any]:
        return self.control({"cmd": "remove", "target": int(target)})

    def set_snr(self, snr_db: float) -> Dict[str, Any]:
        return self.control({"cmd": "snr", "snr_db": float(snr_db)})

    def seed(self, seed: int) -> Dict[str, Any]:
        """Restarts the noise and jitter generator from ``seed``."""
        return self.control({"cmd": "seed", "seed": int(seed)})

    def last_capture(self) -> Dict[str, Any]:
        """``{"captures": N, "scene": {...}}``: how many captures the scope made and the scene
        of the last one (its ground truth)."""
        reply = self.control({"cmd": "last_capture"})
        return {"captures": reply.get("captures"), "scene": reply.get("scene")}
