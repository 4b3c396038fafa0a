"""Phases of a radbench I/O journal (`--trace-io`), shared by the one-shot benchmarks
(`compare_campaign.py --one-shot`, `one_shot_turns.py`). Standard library only."""

import datetime


def journal_times(line):
    """(start, end) of one journal line, seconds since the epoch (`time` is when it was
    written, at the end of the exchange)."""
    end = datetime.datetime.fromisoformat(line["time"].replace("Z", "+00:00")).timestamp()
    return end - line["elapsed_us"] * 1e-6, end


def connect_span(journal):
    """(first connect's start, last identification's end): `*IDN?` answered for the AWG and
    the scope, the ID register (`R 00`) for Tx and Rx."""
    starts, done = [], {}
    asked = {}
    for line in journal:
        who, text = line["instrument"], line.get("text", "")
        start, end = journal_times(line)
        if line["direction"] == "event" and line.get("kind") == "connect":
            starts.append(start)
        elif line["direction"] == "write":
            asked[who] = text
        elif line["direction"] == "read" and who not in done:
            q = asked.get(who, "")
            if q.startswith("*IDN?") and who in ("awg", "scope") or q.startswith("R 00"):
                done[who] = end
    return min(starts), max(done.values())
