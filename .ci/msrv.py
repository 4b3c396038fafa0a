#!/usr/bin/env python3
"""The declared minimum Rust version holds: every package in both lock files (the workspace's and
the Python package's, dev-dependencies included) declares a `rust-version` no newer than ours, and
the crates agree on ours. Our own code's use of newer standard-library items is clippy's
`incompatible_msrv` lint, which reads the same `rust-version` (denied in .ci/run's clippy).

This machine has one toolchain and no way to fetch another, so the check reads what each
dependency declares instead of building with the old compiler. The fix for a failure: keep the
resolver's fallback (`resolver = "3"` picks versions that fit `rust-version`) and run
`cargo update -p <crate>`, or raise `rust-version` and say so in the README.

    python3 .ci/msrv.py        # exit 0: holds; 1: lists what breaks it
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORKSPACES = [ROOT, ROOT / "python"]


def version(text: str) -> tuple[int, ...]:
    parts = [int(p) for p in text.split(".")]
    return tuple(parts + [0] * (3 - len(parts)))


def metadata(workspace: Path) -> dict:
    out = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--locked"],
        cwd=workspace, capture_output=True, text=True, timeout=300,
    )
    if out.returncode != 0:
        sys.exit(f"msrv: cargo metadata in {workspace} failed:\n{out.stderr}")
    return json.loads(out.stdout)


def main() -> int:
    problems = []
    declared = set()
    for workspace in WORKSPACES:
        meta = metadata(workspace)
        members = set(meta["workspace_members"])
        ours = {p["rust_version"] for p in meta["packages"] if p["id"] in members}
        declared |= ours
        if None in ours:
            problems.append(f"{workspace}: a member crate declares no rust-version")
        floor = max((version(v) for v in ours if v), default=None)
        if floor is None:
            continue
        for p in meta["packages"]:
            needed = p.get("rust_version")
            if p["id"] not in members and needed and version(needed) > floor:
                problems.append(
                    f"{workspace.relative_to(ROOT).as_posix() or '.'}/Cargo.lock: {p['name']} {p['version']} needs Rust "
                    f"{needed}, newer than rust-version {'.'.join(map(str, floor))}"
                )
        where = workspace.relative_to(ROOT).as_posix() or "."
        print(f"msrv: {where}: {len(meta['packages'])} packages "
              f"checked against rust-version {'.'.join(map(str, floor))}")
    if len(declared - {None}) > 1:
        problems.append(f"the crates declare different rust-versions: {sorted(declared - {None})}")
    for line in problems:
        print(f"msrv: {line}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
