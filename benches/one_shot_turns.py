"""One-shot `radbench capture` of several radbench binaries taking turns against one lab.

    python3 benches/one_shot_turns.py --bench BENCH.toml --turns 20 OLD_BINARY NEW_BINARY ...

Each turn runs every binary once, in the order given, against the lab of BENCH.toml (a
`mock-lab serve`'s table: start one with `mock-lab serve`, its bench file is what it prints from
`[awg]` on), so the binaries share the same minutes of a busy machine. Phases from radbench's I/O
journal (`--trace-io`) and the time just before the process was spawned, as
`compare_campaign.py --one-shot` reports them (issue 23), plus two of the RF path:

- first byte: spawn to the first journal line's start;
- connect: the first connect's start to the last instrument identified;
- to upload: the last identification to the AWG's first `:ABOR` (the upload's start);
- to RF: spawn to `:OUTP1 ON` (the AWG's outputs switched on);
- instruments: first byte to the last exchange; after last: the last exchange to the exit;
- whole: spawn to exit.

Prints min / median of each, per binary. Standard library only.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from io_journal import connect_span, journal_times


def one_shot(binary, bench, out):
    journal_path = out.with_suffix(".jsonl")
    cmd = [binary, "--trace-io", str(journal_path), "capture", "--bench", str(bench),
           "--allow-rf", "--out", str(out), "--json"]
    spawned = time.time()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{binary} failed ({proc.returncode}): {proc.stderr}")
    journal = [json.loads(x) for x in journal_path.read_text().splitlines()]
    spans = [journal_times(x) for x in journal]
    first = min(s for s, _ in spans)
    last = max(e for _, e in spans)
    c0, c1 = connect_span(journal)

    def start_of(prefix, instrument=None):
        return min(s for (s, _), x in zip(spans, journal)
                   if x["direction"] == "write" and x.get("text", "").startswith(prefix)
                   and instrument in (None, x["instrument"]))

    return {"first byte": first - spawned, "connect": c1 - c0,
            "to upload": start_of(":ABOR", "awg") - c1, "to RF": start_of(":OUTP1 ON") - spawned,
            "instruments": last - first, "after last": spawned + wall - last, "whole": wall}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bench", required=True, type=Path, help="the lab's bench file")
    ap.add_argument("--turns", type=int, default=20)
    ap.add_argument("binaries", nargs="+")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="one_shot_turns."))
    runs = {b: [] for b in args.binaries}
    try:
        for turn in range(args.turns):
            for k, b in enumerate(args.binaries):
                runs[b].append(one_shot(b, args.bench, work / f"{k}-{turn}"))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"{args.turns} turns, load average {os.getloadavg()[0]:.2f} (1 min); ms, min / median")
    for k, b in enumerate(args.binaries):
        print(f"  [{k}] {b}")
    for key in runs[args.binaries[0]][0]:
        cells = "   ".join(f"{1e3 * min(r[key] for r in runs[b]):6.1f} / "
                           f"{1e3 * statistics.median(r[key] for r in runs[b]):6.1f}"
                           for b in args.binaries)
        print(f"  {key:12} {cells}")


if __name__ == "__main__":
    main()
