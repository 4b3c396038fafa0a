"""Processes an archive of captures with radbench on a Dask cluster: what `radbench process
--jobs N ARCHIVE...` does on one machine, spread over Dask workers (here a LocalCluster; give
--scheduler to use a running cluster whose workers have radbench installed).

    python examples/dask_archive.py runs/2026-accuracy runs/more-captures --workers 2

prints one JSON object {folder name: summary} (`radbench process`'s folder names and the
summary.json of each, but `files`). Processing options go after --, as radbench process takes
them: `-- --algorithm music --m 48`.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, Dict, List, Sequence

import dask.bag as db
from distributed import Client, LocalCluster

import radbench


def _one(item, options):
    name, files = item
    return name, radbench.process(files, **options).summary


def process_archive(inputs: Sequence[str], client: Client, **options: Any) -> Dict[str, Dict[str, Any]]:
    """Every capture `radbench process INPUTS` would process, processed on `client`'s workers
    (one task per capture); {folder name: summary}."""
    captures = radbench.captures(*inputs)
    if not captures:
        return {}
    bag = db.from_sequence(list(captures.items()), npartitions=len(captures))
    done = bag.map(_one, options).compute(scheduler=client.get)
    return dict(done)


def _options(argv: List[str]) -> Dict[str, Any]:
    """`--zero-pad 20 --forward-only` -> {"zero_pad": "20", "forward_only": True}."""
    out: Dict[str, Any] = {}
    k = 0
    while k < len(argv):
        name = argv[k].lstrip("-").replace("-", "_")
        if k + 1 < len(argv) and not argv[k + 1].startswith("--"):
            out[name] = argv[k + 1]
            k += 2
        else:
            out[name] = True
            k += 1
    return out


def main(argv: List[str]) -> int:
    own, processing = argv, []
    if "--" in argv:
        cut = argv.index("--")
        own, processing = argv[:cut], argv[cut + 1:]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("inputs", nargs="+", help="capture or run folders, .sigmf-meta files")
    parser.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes")
    parser.add_argument("--threads-per-worker", type=int, default=1)
    parser.add_argument("--scheduler", help="address of a running Dask scheduler instead")
    args = parser.parse_args(own)
    options = _options(processing)
    if args.scheduler:
        with Client(args.scheduler) as client:
            result = process_archive(args.inputs, client, **options)
    else:
        with LocalCluster(n_workers=args.workers, threads_per_worker=args.threads_per_worker,
                          host="127.0.0.1", dashboard_address=None, processes=True) as cluster, \
                Client(cluster) as client:
            result = process_archive(args.inputs, client, **options)
    json.dump(result, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
