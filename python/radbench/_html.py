"""How a :class:`Processed` and a :class:`Run` show in Jupyter: an inline SVG range profile and
small tables (no plotting library needed), and ``Processed.plot`` with matplotlib when it is
installed."""

from __future__ import annotations

import html
from typing import TYPE_CHECKING, Any, List, Optional, Sequence

import numpy as np

if TYPE_CHECKING:
    from . import Processed, Run

#: Most points of the drawn profile (a long profile is reduced to its per-column maxima).
MAX_POINTS = 600
WIDTH, HEIGHT, PAD = 640, 240, 40


def _reduced(x: np.ndarray, y: np.ndarray) -> "tuple[np.ndarray, np.ndarray]":
    if len(x) <= MAX_POINTS:
        return x, y
    edges = np.linspace(0, len(x), MAX_POINTS + 1).astype(int)
    keep = [lo + int(np.argmax(y[lo:hi])) for lo, hi in zip(edges[:-1], edges[1:]) if hi > lo]
    return x[keep], y[keep]


def profile_svg(p: "Processed") -> str:
    """The primary profile in dB over range, the targets marked, as an SVG element."""
    profile = p.profile
    if profile is None or len(profile.range_m) == 0:
        return "<em>no profile</em>"
    with np.errstate(divide="ignore"):
        db = 20.0 * np.log10(np.maximum(profile.amplitude, 1e-300))
    x, y = _reduced(np.asarray(profile.range_m, float), db)
    top = float(np.max(y))
    bottom = max(float(np.min(y)), top - 80.0)
    y = np.clip(y, bottom, top)
    x0, x1 = float(x[0]), float(x[-1]) if x[-1] > x[0] else float(x[0]) + 1.0

    def sx(v: float) -> float:
        return PAD + (v - x0) / (x1 - x0) * (WIDTH - 2 * PAD)

    def sy(v: float) -> float:
        return HEIGHT - PAD - (v - bottom) / max(top - bottom, 1e-9) * (HEIGHT - 2 * PAD)

    points = " ".join(f"{sx(a):.1f},{sy(b):.1f}" for a, b in zip(x, y))
    marks = "".join(
        f'<line x1="{sx(t["range_m"]):.1f}" x2="{sx(t["range_m"]):.1f}" y1="{PAD}" '
        f'y2="{HEIGHT - PAD}" stroke="#d62728" stroke-dasharray="4 3"/>'
        f'<text x="{sx(t["range_m"]) + 3:.1f}" y="{PAD + 12}" font-size="11" fill="#d62728">'
        f'{t["range_m"]:.3f} m</text>'
        for t in p.targets
        if x0 <= t["range_m"] <= x1
    )
    title = html.escape(f"{p.waveform} {p.algorithm}")
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" '
        f'viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif">'
        f'<rect x="{PAD}" y="{PAD}" width="{WIDTH - 2 * PAD}" height="{HEIGHT - 2 * PAD}" '
        f'fill="none" stroke="#999"/>'
        f'<polyline fill="none" stroke="#1f77b4" stroke-width="1" points="{points}"/>{marks}'
        f'<text x="{PAD}" y="{PAD - 8}" font-size="12">{title}: range profile (dB)</text>'
        f'<text x="{PAD}" y="{HEIGHT - 10}" font-size="11">{x0:.2f} m</text>'
        f'<text x="{WIDTH - PAD}" y="{HEIGHT - 10}" font-size="11" text-anchor="end">{x1:.2f} m</text>'
        f'<text x="{PAD - 4}" y="{PAD + 4}" font-size="11" text-anchor="end">{top:.0f}</text>'
        f'<text x="{PAD - 4}" y="{HEIGHT - PAD}" font-size="11" text-anchor="end">{bottom:.0f}</text>'
        "</svg>"
    )


def _table(header: Sequence[str], rows: List[Sequence[Any]]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _num(v: Optional[float], digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def processed_html(p: "Processed") -> str:
    rows = [[_num(t["range_m"]), _num(t["level_db"], 1), _num(t.get("snr_db"), 1)] for t in p.targets]
    parts = [profile_svg(p), _table(["range (m)", "level (dB)", "SNR (dB)"], rows or [["none", "", ""]])]
    if p.payload:
        parts.append(f"<p>payload: {html.escape(str(p.payload.get('text')))} "
                     f"({p.payload.get('bit_errors')} bit errors in {p.payload.get('bits')})</p>")
    parts += [f"<p>warning: {html.escape(w)}</p>" for w in p.warnings]
    return "<div>" + "".join(parts) + "</div>"


def run_html(r: "Run") -> str:
    rows = []
    results = {s["index"]: s for s in (r.results or {}).get("steps", [])}
    for step in r.steps:
        result = step.result or results.get(step.index)
        measured = "-"
        if result:
            found = []
            for name, algo in result.get("algorithms", {}).items():
                found.append(name + ": " + ", ".join(_num(t.get("range_m")) for t in algo.get("targets", [])))
            measured = "; ".join(found)
        nominal = step.plan.get("nominal", {}) if isinstance(step.plan, dict) else {}
        rows.append([step.index, html.escape(str(nominal.get("targets", nominal))), measured])
    plan = r.manifest.get("plan", {})
    name = r.manifest.get("name") or (plan.get("name") if isinstance(plan, dict) else None) or r.path
    title = html.escape(f"{name}: {r.status}")
    return f"<div><p><b>{title}</b> ({html.escape(r.path)})</p>" + _table(
        ["step", "nominal", "measured (m)"], rows) + "</div>"


def plot(p: "Processed", ax: Any = None) -> Any:
    """The profiles in dB over range with the targets marked, on ``ax`` (a new figure's when
    ``None``); needs matplotlib."""
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("Processed.plot needs matplotlib: pip install matplotlib") from e
    if ax is None:
        _, ax = plt.subplots()
    for profile in p.profiles:
        ax.plot(profile.range_m, profile.db, label=profile.label or p.algorithm, linewidth=0.8)
    for t in p.targets:
        ax.axvline(t["range_m"], color="tab:red", linestyle="--", linewidth=0.8)
    ax.set_xlabel("range (m)")
    ax.set_ylabel("dB")
    ax.set_title(f"{p.waveform} {p.algorithm}")
    if len(p.profiles) > 1:
        ax.legend()
    return ax
