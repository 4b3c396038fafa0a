"""The transmitted waveforms, made by radbench's own generators with ``radbench capture``'s
parameters and defaults (the thesis': MSK-LFM 1 GHz, 10 us, 128 bits at 16 GSa/s; OFDM 128
subcarriers, QPSK, CP 1/4, 100 symbols, 16x oversampled), and the AWG's 8-bit codes.

>>> w = msk_lfm(bandwidth=2e9)
>>> w.samples.dtype, w.i.dtype, w.sample_rate_hz
(dtype('complex128'), dtype('int8'), 16000000000.0)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Dict, Optional

import numpy as np

from . import _radbench

__all__ = ["Waveform", "msk_lfm", "ofdm"]


@dataclass
class Waveform:
    """One repetition of a transmitted waveform.

    ``samples``: the complex baseband per unit full scale (what the AWG's codes represent:
    radbench's correlation reference); ``i``, ``q``: the AWG's int8 codes, ``marker_high_samples``
    the marker's high samples at the start of each repetition (the scope's trigger); ``bits``:
    every bit sent (framing included); ``description``: what a capture records about it."""

    kind: str
    samples: np.ndarray
    i: np.ndarray
    q: np.ndarray
    marker_high_samples: int
    bits: np.ndarray
    sample_rate_hz: float
    bandwidth_hz: float
    seed: int
    payload: Optional[bytes]
    description: Dict[str, Any]

    def marker(self) -> np.ndarray:
        """The marker as uint8 per sample (1 high, 0 low), as the M8195A's marker bytes."""
        m = np.zeros(len(self.i), dtype=np.uint8)
        m[: self.marker_high_samples] = 1
        return m


def _make(kind: str, options: Dict[str, Any]) -> Waveform:
    from . import _argv

    d = _radbench.transmission(kind, _argv(options))
    payload = d["payload"]
    return Waveform(
        kind=kind,
        samples=d["samples"],
        i=d["i"],
        q=d["q"],
        marker_high_samples=d["marker_high_samples"],
        bits=d["bits"],
        sample_rate_hz=d["sample_rate_hz"],
        bandwidth_hz=d["bandwidth_hz"],
        seed=d["seed"],
        payload=bytes(payload) if payload is not None else None,
        description=json.loads(d["description_json"]),
    )


def msk_lfm(
    *,
    bandwidth: Optional[float] = None,
    sample_rate: Optional[float] = None,
    pulse_us: Optional[float] = None,
    bits_per_pulse: Optional[int] = None,
    band: Optional[str] = None,
    payload: Optional[str] = None,
    seed: Optional[int] = None,
) -> Waveform:
    """The MSK-LFM waveform (``radbench capture --waveform msk-lfm``'s options; ``None`` keeps
    its default: bandwidth 1e9 Hz, sample_rate 16e9 Sa/s, pulse_us 10, bits_per_pulse 128,
    band "centred" (or "upper", "lower"), PRBS bits of seed 1 unless a ``payload`` text)."""
    return _make("msk-lfm", dict(bandwidth=bandwidth, sample_rate=sample_rate, pulse_us=pulse_us,
                                 bits_per_pulse=bits_per_pulse, band=band, payload=payload, seed=seed))


def ofdm(
    *,
    bandwidth: Optional[float] = None,
    subcarriers: Optional[int] = None,
    oversampling: Optional[int] = None,
    cp_fraction: Optional[float] = None,
    symbols: Optional[int] = None,
    payload: Optional[str] = None,
    seed: Optional[int] = None,
) -> Waveform:
    """The OFDM waveform (``radbench capture --waveform ofdm``'s options; ``None`` keeps its
    default: bandwidth 1e9 Hz, 128 subcarriers, oversampling 16, cp_fraction 0.25, 100 symbols,
    PRBS bits of seed 1 unless a ``payload`` text)."""
    return _make("ofdm", dict(bandwidth=bandwidth, subcarriers=subcarriers, oversampling=oversampling,
                              cp_fraction=cp_fraction, symbols=symbols, payload=payload, seed=seed))
