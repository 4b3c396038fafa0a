import os
from typing import Any, Callable, Dict, Optional, Union

from . import Processed, Run
from ._lab import MockLab

PathLike = Union[str, "os.PathLike[str]"]
SceneLike = Union[None, str, "os.PathLike[str]", Dict[str, Any]]

class Bench:
    def __init__(
        self,
        bench: Union[None, PathLike, MockLab] = ...,
        *,
        scene: SceneLike = ...,
        allow_rf: bool = ...,
        scope_model: Optional[str] = ...,
        trace_io: Optional[PathLike] = ...,
        manual_front_ends_confirmed: bool = ...,
    ) -> None: ...
    def __enter__(self) -> "Bench": ...
    def __exit__(self, *exc: Any) -> None: ...
    def close(self) -> Optional[str]: ...
    @property
    def closed(self) -> bool: ...
    def capture(
        self,
        waveform: str = ...,
        *,
        algorithm: Optional[str] = ...,
        correction: Optional[str] = ...,
        repetitions: Optional[int] = ...,
        out: Optional[PathLike] = ...,
        **processing: Any,
    ) -> Processed: ...
    def calibrate(self, reference_range: float, *, search: float = ...) -> Dict[str, Any]: ...
    def calibrate_response(
        self,
        reference_range: float,
        waveform: str = ...,
        *,
        repetitions: int = ...,
        gate_ns: Optional[float] = ...,
        reflector: Optional[float] = ...,
        out: Optional[PathLike] = ...,
        force: bool = ...,
        **waveform_options: Any,
    ) -> Dict[str, Any]: ...
    def campaign(
        self,
        spec: Union[PathLike, Dict[str, Any]],
        *,
        out: Optional[PathLike] = ...,
        retries: Optional[int] = ...,
    ) -> "Campaign": ...
    def doctor(self) -> Dict[str, Any]: ...

class Campaign:
    dir: Optional[str]
    def run(self, on_step: Optional[Callable[[Dict[str, Any]], Any]] = ...) -> Run: ...
    def resume(self, on_step: Optional[Callable[[Dict[str, Any]], Any]] = ...) -> Run: ...
