"""Benchmarks.  ``python benchmarks/bench.py NAME``; the last line printed is one JSON object of figures.

NAME:
    loop    the direct loop (FMI-free) for the G1 50 s learning run: the stepping loop only, recording
            every output, median of several runs -> direct_s, direct_us_per_step (target <= 20 us)
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys


def bench_loop(repeats: int) -> dict[str, float]:
    from wmr_cosim.components.direct_loop import run_direct

    run_direct(t_stop=2.0)  # warm up imports and caches
    walls, walls_norec = [], []
    steps = 0
    for _ in range(repeats):
        r = run_direct(t_stop=50.0, h=0.002, record=True)
        walls.append(r.wall_s)
        steps = r.steps
        walls_norec.append(run_direct(t_stop=50.0, h=0.002, record=False).wall_s)
    direct_s = statistics.median(walls)
    return {
        "steps": steps,
        "repeats": repeats,
        "direct_s": round(direct_s, 4),
        "direct_us_per_step": round(direct_s / steps * 1e6, 2),
        "direct_norecord_us_per_step": round(statistics.median(walls_norec) / steps * 1e6, 2),
        "direct_min_us_per_step": round(min(walls) / steps * 1e6, 2),
    }


BENCHES = {"loop": bench_loop}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("name", choices=sorted(BENCHES))
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    figures = BENCHES[args.name](args.repeats)
    print(f"# {args.name} on {platform.python_implementation()} {platform.python_version()}, "
          f"{platform.machine()}", file=sys.stderr, flush=True)
    print(json.dumps({"bench": args.name, **figures}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
