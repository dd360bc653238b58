#!/usr/bin/env python3
"""How much CPU other processes take while a benchmark runs (Linux /proc).

    python3 cpu_other.py PGID OUT &    # ... benchmark ...; kill %1

Every second, sums the CPU time gained by every process outside process group PGID (the
benchmark's), and on SIGTERM writes to OUT one JSON object: seconds sampled and the mean and
maximum cores' worth of CPU the others used, plus the per-second series. A process that exits
between two samples loses its last second, so short-lived processes are slightly undercounted.
"""
import json
import os
import signal
import sys
import time

TICK = os.sysconf("SC_CLK_TCK")


def others(pgid):
    """CPU ticks (utime + stime) of every process not in process group `pgid`, by pid."""
    out = {}
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/stat") as fh:
                f = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        # f[0] = state (field 3), f[2] = pgrp (field 5), f[11], f[12] = utime, stime (14, 15)
        if int(f[2]) != pgid:
            out[pid] = int(f[11]) + int(f[12])
    return out


def main():
    pgid, path = int(sys.argv[1]), sys.argv[2]
    series = []
    prev, t_prev = others(pgid), time.monotonic()

    def finish(*_):
        mean = sum(series) / len(series) if series else 0.0
        with open(path, "w") as fh:
            json.dump(dict(seconds=len(series), mean_cores=mean, max_cores=max(series, default=0.0),
                           series=[round(c, 2) for c in series]), fh)
        sys.exit(0)

    signal.signal(signal.SIGTERM, finish)
    while True:
        time.sleep(1.0)
        cur, t = others(pgid), time.monotonic()
        gained = sum(v - prev.get(pid, 0) for pid, v in cur.items())
        series.append(max(gained, 0) / TICK / (t - t_prev))
        prev, t_prev = cur, t


if __name__ == "__main__":
    main()
