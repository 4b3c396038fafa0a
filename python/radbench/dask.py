"""Archive processing on Dask: the captures a catalog query selects, each processed into a
folder addressed by content, the same unit as ``radbench process --from-catalog`` (the Rust core,
called in-process, no subprocess). See docs/catalog.md.

Each unit writes ``OUT/<input>-<options>-v<version>`` under a hidden temporary name and renames
it when complete, and skips a unit whose folder exists: a rerun does only what is missing, and a
worker killed mid-unit leaves no half-written or duplicated result (Dask runs its task again on
another worker, which finds the folder done or writes it). The output set is byte-identical to
``radbench process --from-catalog QUERY --out OUT``'s with the same options.

Example (a LocalCluster of two worker processes; in a script, under
``if __name__ == "__main__":``, since the workers import the script again)::

    from distributed import Client, LocalCluster
    import radbench.dask as rd

    with rd.worker_environment(), \
            LocalCluster(n_workers=2, threads_per_worker=1) as cluster, Client(cluster):
        bag = rd.process_bag("runs/catalog.sqlite", "waveform = ofdm", "runs/processed",
                             algorithm="music")
        done = bag.compute()
    rd.register("runs/catalog.sqlite", "runs/processed", done, algorithm="music")

On a cluster, only the ``Client`` changes (``Client("tcp://scheduler:8786")``); the catalog, the
captures and ``out`` must be at the same paths on every worker (a shared file system).

dask is optional: ``pip install "radbench[dask]"`` (dask[bag] and distributed).
"""

from __future__ import annotations

import contextlib
import os
from typing import Any, Dict, Iterable, Iterator, List, Mapping, Optional, Union

from . import _keywords, _radbench

PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["WORKER_CONFIG", "worker_environment", "units", "process_unit", "process_bag", "register"]

#: Dask configuration for the workers that run radbench's units (see :func:`worker_environment`):
#: each worker process's memory set up as the command line sets up its own (``src/bin/radbench/main.rs``).
#: Dask's nanny starts every worker with ``MALLOC_TRIM_THRESHOLD_=65536``, which also switches
#: off glibc's adaptive mmap threshold: each of a unit's large buffers is then mapped and faulted
#: in afresh, and a unit runs ~30 % slower (measured: 2 workers, 9.8 against 13.4 captures/s;
#: docs/catalog.md). Here glibc keeps freed memory for reuse (mmap threshold 256 MiB, trim
#: threshold 512 MiB, top pad 64 MiB, as ``radbench`` itself), and radbench's buffers of 1 MiB or
#: more sit on transparent huge pages, reused once freed (``RADBENCH_HUGE_PAGES=on``, the
#: extension's allocator, off by default in other processes): a quarter fewer page faults and
#: less time in the TLB's misses. The cost: a worker's resident size stays at its peak (a few
#: units' buffers). Workers started with ``dask worker`` read the same keys from their own
#: configuration.
#:
#: The rest quiets what a worker and the scheduler do beside the tasks, which on a small machine
#: competes with them for the cores: the statistical profiler (it samples the task thread every
#: 10 ms, and a radbench unit is one call into Rust it cannot see inside) and the system,
#: memory and event-loop monitors at 2 s, 1 s and 200 ms instead of 0.5 s, 0.1 s and 20 ms.
#: Together they halved the scheduler process's CPU time (0.5 -> 0.2 s per 96 units).
WORKER_CONFIG: Dict[str, Any] = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": str(512 << 20),
    "distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": str(256 << 20),
    "distributed.nanny.pre-spawn-environ.MALLOC_TOP_PAD_": str(64 << 20),
    "distributed.nanny.pre-spawn-environ.RADBENCH_HUGE_PAGES": "on",
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.tick.interval": "200ms",
}


@contextlib.contextmanager
def worker_environment() -> Iterator[None]:
    """Starts the workers of the cluster made inside it with radbench's memory set-up instead of
    Dask's malloc trim threshold, and Dask's background work quieted (:data:`WORKER_CONFIG`):
    ``with rd.worker_environment(), LocalCluster(...) as cluster:``. Also removes Dask's
    threshold from this process's environment, where an earlier cluster's nanny leaves it (and
    every later worker would inherit it). Needs dask."""
    import dask

    os.environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    with dask.config.set(WORKER_CONFIG):
        yield


def units(
    catalog: PathLike, query: str = "all", *, captures: Optional[Iterable[Mapping[str, Any]]] = None
) -> List[Dict[str, str]]:
    """The units to process: the captures ``query`` selects in ``catalog`` (the language of
    ``radbench process --from-catalog``, e.g. ``"waveform = ofdm and since = 2026-11-01"``), or
    the records ``captures`` (from ``radbench.catalog(path).captures(**filters)``). Each is a
    dict ``{"input_dir", "input_sha256"}``."""
    dirs = None if captures is None else [os.fspath(c["dir"]) for c in captures]
    found = _radbench.archive_units(os.fspath(catalog), query, dirs)
    return [{"input_dir": os.fspath(d), "input_sha256": sha} for d, sha in found]


def process_unit(
    unit: Mapping[str, str], out: PathLike, markers: Optional[PathLike] = None, **processing: Any
) -> Dict[str, str]:
    """One unit processed into ``out`` unless done: ``unit`` plus ``status`` (``"written"`` or
    ``"skipped"``) and ``out_dir``. ``processing``: ``radbench.process``'s keywords. ``markers``:
    a folder where each computation started leaves a file (to count work)."""
    status, out_dir = _radbench.archive_process_unit(
        os.fspath(unit["input_dir"]),
        unit["input_sha256"],
        os.fspath(out),
        _keywords(processing),
        None if markers is None else os.fspath(markers),
    )
    return {**unit, "status": status, "out_dir": os.fspath(out_dir)}


def process_bag(
    catalog: PathLike,
    query: str = "all",
    out: Optional[PathLike] = None,
    *,
    captures: Optional[Iterable[Mapping[str, Any]]] = None,
    markers: Optional[PathLike] = None,
    **processing: Any,
) -> Any:
    """A :class:`dask.bag.Bag` of the selected units, one per partition, each mapped through
    :func:`process_unit` (lazy: ``.compute()`` runs it on the current scheduler). ``out``
    defaults to ``processed/`` beside the catalog, as the command's. Register the results with
    :func:`register`."""
    try:
        import dask.bag as db
        from dask.base import tokenize
    except ImportError as e:
        raise ImportError(
            "radbench.dask.process_bag needs dask: pip install 'dask[bag]' distributed "
            "(or pip install 'radbench[dask]')"
        ) from e
    if out is None:
        out = os.path.join(os.path.dirname(os.path.abspath(os.fspath(catalog))), "processed")
    selected = units(catalog, query, captures=captures)
    if not selected:
        return db.from_sequence([], npartitions=1)
    # One task per unit. `from_sequence(...).map(...)` makes two per unit, which Dask does not
    # fuse: each worker then waited ~2 ms between them, 5 % of the wall time (measured).
    name = "radbench-process-" + tokenize(selected, os.fspath(out), markers, processing)
    graph = {
        (name, i): (_process_partition, unit, os.fspath(out), markers, processing)
        for i, unit in enumerate(selected)
    }
    return db.Bag(graph, name, len(selected))


def _process_partition(
    unit: Mapping[str, str], out: str, markers: Optional[PathLike], processing: Dict[str, Any]
) -> List[Dict[str, str]]:
    """A bag's partition: the one unit, processed."""
    return [process_unit(unit, out, markers, **processing)]


def register(
    catalog: PathLike, out: PathLike, done: Iterable[Mapping[str, str]], **processing: Any
) -> int:
    """Registers computed results (``process_bag(...).compute()``) in the catalog's
    ``processed`` table, as the command does, and removes the temporary folders of done units
    in ``out`` (left by killed workers); how many were removed. ``processing``: the keywords
    the units were processed with."""
    rows = [(d["input_dir"], d["input_sha256"], d["out_dir"]) for d in done]
    return _radbench.archive_register(
        os.fspath(catalog), os.fspath(out), _keywords(processing), rows
    )
