import os
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import waveform as waveform
from ._bench import Bench as Bench
from ._catalog import Catalog as Catalog
from ._catalog import catalog as catalog
from ._lab import MockLab as MockLab
from .errors import InputError as InputError
from .errors import InstrumentError as InstrumentError
from .errors import ProcessingError as ProcessingError
from .errors import RadbenchError as RadbenchError

__version__: str

PathLike = Union[str, os.PathLike[str]]
CaptureLike = Union[PathLike, Sequence[PathLike], "Capture"]

class Capture:
    path: str
    files: List[str]
    iq: Union[npt.NDArray[np.complex128], List[npt.NDArray[np.complex128]]]
    capture_rate_hz: float
    iq_t0_s: npt.NDArray[np.float64]
    decimated: Optional[Union[npt.NDArray[np.complex128], List[npt.NDArray[np.complex128]]]]
    processing_rate_hz: Optional[float]
    decimated_t0_s: npt.NDArray[np.float64]
    metadata: Dict[str, Any]
    radbench: Dict[str, Any]
    scene: Optional[Dict[str, Any]]
    not_decimated: Optional[str]
    @property
    def repetitions(self) -> int: ...
    @property
    def true_ranges_m(self) -> List[float]: ...

class Profile:
    label: str
    range_m: npt.NDArray[np.float64]
    amplitude: npt.NDArray[np.float64]
    @property
    def db(self) -> npt.NDArray[np.float64]: ...

class Processed:
    summary: Dict[str, Any]
    options: Dict[str, Any]
    profiles: List[Profile]
    threshold: npt.NDArray[np.float64]
    residual: npt.NDArray[np.float64]
    complex_profile: Optional[npt.NDArray[np.complex128]]
    aligned: npt.NDArray[np.complex128]
    noise_db: Optional[float]
    @property
    def targets(self) -> List[Dict[str, Any]]: ...
    @property
    def ranges_m(self) -> List[float]: ...
    @property
    def width_3db_cm(self) -> Optional[float]: ...
    @property
    def sidelobe_db(self) -> Optional[float]: ...
    @property
    def snr_db(self) -> Optional[float]: ...
    @property
    def payload(self) -> Optional[Dict[str, Any]]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def algorithm(self) -> str: ...
    @property
    def waveform(self) -> str: ...
    @property
    def profile(self) -> Optional[Profile]: ...
    def _repr_html_(self) -> str: ...
    def plot(self, ax: Any = ...) -> Any: ...

class Step:
    index: int
    path: str
    capture: Optional[Capture]
    summary: Optional[Dict[str, Any]]
    result: Optional[Dict[str, Any]]
    plan: Dict[str, Any]

class Run:
    path: str
    manifest: Dict[str, Any]
    steps: List[Step]
    results: Optional[Dict[str, Any]]
    @property
    def status(self) -> str: ...
    def _repr_html_(self) -> str: ...

def read_capture(path: Union[PathLike, Sequence[PathLike]]) -> Capture: ...
STALE_REASON: str

def read_run(path: PathLike, *, captures: bool = ...) -> Run: ...
def process(
    capture_or_samples: Union[CaptureLike, npt.NDArray[np.complexfloating[Any, Any]]],
    *,
    waveform: Optional[str] = ...,
    algorithm: Optional[str] = ...,
    capture_rate: Optional[float] = ...,
    **options: Any,
) -> Processed: ...
def captures(*inputs: PathLike) -> Dict[str, List[str]]: ...
