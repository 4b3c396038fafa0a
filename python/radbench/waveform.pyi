from typing import Any, Dict, Optional

import numpy as np
import numpy.typing as npt

class Waveform:
    kind: str
    samples: npt.NDArray[np.complex128]
    i: npt.NDArray[np.int8]
    q: npt.NDArray[np.int8]
    marker_high_samples: int
    bits: npt.NDArray[np.uint8]
    sample_rate_hz: float
    bandwidth_hz: float
    seed: int
    payload: Optional[bytes]
    description: Dict[str, Any]
    def marker(self) -> npt.NDArray[np.uint8]: ...

def msk_lfm(
    *,
    bandwidth: Optional[float] = ...,
    sample_rate: Optional[float] = ...,
    pulse_us: Optional[float] = ...,
    bits_per_pulse: Optional[int] = ...,
    band: Optional[str] = ...,
    payload: Optional[str] = ...,
    seed: Optional[int] = ...,
) -> Waveform: ...
def ofdm(
    *,
    bandwidth: Optional[float] = ...,
    subcarriers: Optional[int] = ...,
    oversampling: Optional[int] = ...,
    cp_fraction: Optional[float] = ...,
    symbols: Optional[int] = ...,
    payload: Optional[str] = ...,
    seed: Optional[int] = ...,
) -> Waveform: ...
