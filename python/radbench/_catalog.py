"""The run catalog from Python: ``radbench.catalog("runs/catalog.sqlite")``.

Plain :mod:`sqlite3` over the catalog's documented schema (docs/catalog.md): the schema is the
interface, so this reads what ``radbench runs index`` and the commands write, read-only, and
never waits for a writer (WAL mode). Every filter value is a bound parameter.

Example::

    cat = radbench.catalog("runs/catalog.sqlite")
    cat.runs(kind="accuracy", scope="uxr", since="2026-11-01",
             where={"max_abs_error_m": ("<", 1e-3)})
    cat.runs(kind="accuracy").to_pandas()
"""

from __future__ import annotations

import os
import re
import sqlite3
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

__all__ = ["Catalog", "Records", "catalog"]

_OPS = {"<": "<", "<=": "<=", ">": ">", ">=": ">=", "=": "=", "==": "=", "!=": "<>"}
_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}(T\d{2}:\d{2}:\d{2}(\.\d+)?Z?)?$")

_RUN_COLUMNS = (
    "run_id, dir, name, sweep, status, reason, created, updated, radbench_version, git_commit, "
    "simulated, bench_file, waveforms, algorithms, scope_idn, awg_idn, calibration_sha256, "
    "steps_total, steps_done"
)
_CAPTURE_COLUMNS = (
    "dir, origin, run_id, step, measured_at, waveform, algorithm, scope_idn, simulated, "
    "radbench_version, targets, snr_db, summary_sha256"
)


class Records(list):
    """A list of records (one ``dict`` each); :meth:`to_pandas` makes it a DataFrame."""

    def to_pandas(self) -> Any:
        """The records as a :class:`pandas.DataFrame` (pandas must be installed)."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("to_pandas() needs pandas: pip install pandas") from e
        return pd.DataFrame.from_records(list(self))


def _time(field: str, text: str) -> str:
    if not isinstance(text, str) or not _DATE.match(text):
        raise ValueError(
            f"{field}={text!r}: give a UTC date or time, YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ"
        )
    return text + "T00:00:00" if len(text) == 10 else text.rstrip("Z")


def _conditions(where: Union[None, str, Mapping[str, Any]]) -> List[Tuple[str, str, float]]:
    """``where`` as (metric, SQL operator, number) terms: a dict ``{"metric": ("<", 1e-3)}`` (a
    bare number means ``=``) or the command line's text ``"max_abs_error_m < 1e-3 and ..."``."""
    if where is None:
        return []
    terms: List[Tuple[str, str, Any]] = []
    if isinstance(where, str):
        for term in re.split(r"\s+and\s+", where.strip(), flags=re.IGNORECASE):
            m = re.fullmatch(r"\s*([A-Za-z0-9_.\-]+)\s*(<=|>=|!=|==|<|>|=)\s*(\S+)\s*", term)
            if not m:
                raise ValueError(
                    f"where: `{term}` is not `METRIC OP NUMBER` (OP one of <, <=, >, >=, =, !=)"
                )
            terms.append((m.group(1), m.group(2), m.group(3)))
    else:
        for metric, cond in where.items():
            op, value = cond if isinstance(cond, (tuple, list)) else ("=", cond)
            terms.append((metric, op, value))
    out = []
    for metric, op, value in terms:
        if op not in _OPS:
            raise ValueError(f"where: operator {op!r} of {metric}: allowed: {', '.join(_OPS)}")
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"where: {metric} {op} {value!r}: not a number") from None
        if number != number or number in (float("inf"), float("-inf")):
            raise ValueError(f"where: {metric} {op} {value!r}: not a finite number")
        out.append((str(metric), _OPS[op], number))
    return out


class Catalog:
    """A run catalog (``catalog.sqlite``), opened read-only."""

    def __init__(self, path: Union[str, "os.PathLike[str]"]):
        self.path = os.fspath(path)
        if not os.path.isfile(self.path):
            raise FileNotFoundError(
                f"no catalog at {self.path}: `radbench runs index DIR` builds it"
            )
        uri = "file:" + os.path.abspath(self.path) + "?mode=ro"
        self._conn = sqlite3.connect(uri, uri=True, check_same_thread=False)
        self._conn.row_factory = sqlite3.Row

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> "Catalog":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _rows(self, sql: str, args: Sequence[Any]) -> Records:
        return Records(dict(r) for r in self._conn.execute(sql, list(args)))

    def runs(
        self,
        *,
        kind: Optional[str] = None,
        since: Optional[str] = None,
        until: Optional[str] = None,
        waveform: Optional[str] = None,
        scope: Optional[str] = None,
        calibration: Optional[str] = None,
        status: Optional[str] = None,
        where: Union[None, str, Mapping[str, Any]] = None,
        limit: Optional[int] = None,
    ) -> Records:
        """The runs every given filter selects, newest first, as ``radbench runs query`` does:
        ``kind`` (campaign name or sweep), ``since``/``until`` (UTC date or time, on
        ``created``), ``waveform``, ``scope`` (text in its ``*IDN?``), ``calibration`` (SHA-256
        prefix, or ``"none"``), ``status`` and ``where`` over the run metrics. Each record holds
        the ``runs`` columns and ``metrics`` (a dict)."""
        sql = f"SELECT {_RUN_COLUMNS} FROM runs r WHERE 1"
        args: List[Any] = []
        if kind is not None:
            sql += " AND (r.name = ? OR r.sweep = ?)"
            args += [kind, kind]
        if since is not None:
            sql += " AND r.created >= ?"
            args.append(_time("since", since))
        if until is not None:
            sql += " AND r.created < ?"
            args.append(_time("until", until))
        if waveform is not None:
            sql += " AND instr(',' || r.waveforms || ',', ',' || ? || ',') > 0"
            args.append(waveform)
        if scope is not None:
            sql += " AND instr(lower(coalesce(r.scope_idn, '')), lower(?)) > 0"
            args.append(scope)
        if calibration == "none":
            sql += " AND r.calibration_sha256 IS NULL"
        elif calibration is not None:
            sql += " AND substr(r.calibration_sha256, 1, length(?)) = lower(?)"
            args += [calibration, calibration]
        if status is not None:
            if status not in ("complete", "interrupted", "running"):
                raise ValueError(
                    f"status={status!r}: allowed: complete, interrupted, running"
                )
            sql += " AND r.status = ?"
            args.append(status)
        for metric, op, number in _conditions(where):
            # `op` comes from _OPS, never from the caller's text.
            sql += (
                " AND EXISTS (SELECT 1 FROM run_metrics m WHERE m.run_id = r.run_id"
                f" AND m.name = ? AND m.value {op} ?)"
            )
            args += [metric, number]
        sql += " ORDER BY r.created DESC, r.run_id"
        if limit is not None:
            sql += " LIMIT ?"
            args.append(int(limit))
        records = self._rows(sql, args)
        metrics: Dict[str, Dict[str, float]] = {r["run_id"]: {} for r in records}
        if records:
            for row in self._conn.execute("SELECT run_id, name, value FROM run_metrics"):
                if row[0] in metrics:
                    metrics[row[0]][row[1]] = row[2]
        for r in records:
            r["simulated"] = bool(r["simulated"])
            r["metrics"] = metrics[r["run_id"]]
        return records

    def captures(
        self,
        *,
        since: Optional[str] = None,
        until: Optional[str] = None,
        waveform: Optional[str] = None,
        scope: Optional[str] = None,
        origin: Optional[str] = None,
        run_id: Optional[str] = None,
        limit: Optional[int] = None,
    ) -> Records:
        """The captures (``capture``, ``process`` and ``campaign`` step folders) the filters
        select, newest first: ``since``/``until`` on ``measured_at``, ``waveform``, ``scope``,
        ``origin``, ``run_id``."""
        sql = f"SELECT {_CAPTURE_COLUMNS} FROM captures WHERE 1"
        args: List[Any] = []
        if since is not None:
            sql += " AND measured_at >= ?"
            args.append(_time("since", since))
        if until is not None:
            sql += " AND measured_at < ?"
            args.append(_time("until", until))
        if waveform is not None:
            sql += " AND waveform = ?"
            args.append(waveform)
        if scope is not None:
            sql += " AND instr(lower(coalesce(scope_idn, '')), lower(?)) > 0"
            args.append(scope)
        if origin is not None:
            sql += " AND origin = ?"
            args.append(origin)
        if run_id is not None:
            sql += " AND run_id = ?"
            args.append(run_id)
        sql += " ORDER BY measured_at DESC, dir"
        if limit is not None:
            sql += " LIMIT ?"
            args.append(int(limit))
        return self._rows(sql, args)

    def steps(self, run_id: str) -> Records:
        """Every step of run ``run_id`` (one record per algorithm)."""
        return self._rows(
            "SELECT * FROM steps WHERE run_id = ? ORDER BY step, algorithm", [run_id]
        )

    def to_pandas(self, table: str = "runs") -> Any:
        """A whole table of the catalog as a DataFrame (``runs``, ``run_metrics``, ``steps``,
        ``captures``, ``targets``, ``calibrations``, ``instruments``, ``assets`` or
        ``processed``)."""
        tables = (
            "runs", "run_metrics", "steps", "captures", "targets", "calibrations",
            "instruments", "assets", "processed",
        )
        if table not in tables:
            raise ValueError(f"table={table!r}: allowed: {', '.join(tables)}")
        return self._rows(f"SELECT * FROM {table}", []).to_pandas()


def catalog(path: Union[str, "os.PathLike[str]"] = os.path.join("runs", "catalog.sqlite")) -> Catalog:
    """The run catalog at ``path`` (default ``runs/catalog.sqlite``), read-only."""
    return Catalog(path)
