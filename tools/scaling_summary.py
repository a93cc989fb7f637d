#!/usr/bin/env python3
"""Summary of tools/scaling_check.sh's runs as markdown (standard library only).

Usage: python3 tools/scaling_summary.py SOFT_FLOOR.csv WEAK_SETUP.csv CORES [WEAK_SIDE.csv]

SOFT_FLOOR.csv: `softcontact bench --csv` rows of the soft floor's variants, whose scene
files are named soft_floor_<variant>.yaml (split, forces, whole), in rounds: the k-th run
of each variant at a rank count belongs to round k. WEAK_SETUP.csv: rows of one chess
container per rank (weakN.yaml). CORES: the node's cores (runs with more ranks are marked
oversubscribed). WEAK_SIDE.csv: the control, one-rank runs of one container started N at
once (sideN.yaml), N rows per round in a row. Any file may be missing (that part is
skipped).

Issue 19's criteria, as checked here:
- Done-when 2, at 4 ranks: "split" faster than "whole" (steps per second) in every round,
  and its compute imbalance (bench's, wall time of forces, detection and depth, max over
  mean of the ranks) under 1.1 in every round.
- Done-when 3: the median set-up at the largest rank count is no more than the largest
  set-up of one rank over the rounds (the growth is within the run-to-run spread).
  With the control, the growth at N ranks is split in two: the node's (the median over
  the rounds of the slowest of the N side-by-side runs, less one rank's median) and the
  code's (the N-rank median less that). Reported, not part of the verdict.
"""
import csv
import os
import re
import statistics
import sys


def rows_of(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def variant_of(row):
    name = os.path.splitext(os.path.basename(row["path"]))[0]
    return name[len("soft_floor_"):] if name.startswith("soft_floor_") else name


def fmt(x, digits=3):
    return f"{x:.{digits}f}"


def soft_floor(rows, cores, out):
    if not rows:
        return
    out.append("## Soft floor: split, forces only, whole\n")
    out.append("`bench inputs/soft_floor.yaml` (variants: `split` as shipped, `forces` with "
               "`split_detection: false`, `whole` with `split_objects: false`), one thread per rank; "
               f"warm-up {rows[0]['warmup']} steps, {rows[0]['steps']} timed.\n")
    runs = {}  # (ranks, variant) -> rows in order
    for r in rows:
        runs.setdefault((int(r["ranks"]), variant_of(r)), []).append(r)
    out.append("| ranks | variant | rounds | steps/s (median) | compute imbalance (median, max) "
               "| CPU imbalance (median) | peak MiB (max rank, max) |")
    out.append("| ---: | --- | ---: | ---: | --- | ---: | ---: |")
    ranks = sorted({k[0] for k in runs})
    variants = ["split", "forces", "whole"]
    for n in ranks:
        for v in variants:
            rs = runs.get((n, v), [])
            if not rs:
                continue
            sps = [float(r["steps_per_second"]) for r in rs]
            imb = [float(r["compute_imbalance"]) for r in rs]
            cpu = [float(r["cpu_imbalance"]) for r in rs]
            mib = [float(r["rss_max_mib"]) for r in rs]
            over = " (oversubscribed)" if n > cores else ""
            out.append(f"| {n}{over} | {v} | {len(rs)} | {fmt(statistics.median(sps), 1)} | "
                       f"{fmt(statistics.median(imb))}, {fmt(max(imb))} | {fmt(statistics.median(cpu))} | "
                       f"{fmt(max(mib), 1)} |")
    out.append("")
    out.append("Ratios of steps per second within each round (above 1: the first is faster):\n")
    out.append("| ranks | ratio | per round | median | rounds faster |")
    out.append("| ---: | --- | --- | ---: | ---: |")
    for n in ranks:
        for a, b in (("split", "whole"), ("forces", "whole"), ("split", "forces")):
            ra, rb = runs.get((n, a), []), runs.get((n, b), [])
            k = min(len(ra), len(rb))
            if k == 0:
                continue
            q = [float(ra[i]["steps_per_second"]) / float(rb[i]["steps_per_second"]) for i in range(k)]
            out.append(f"| {n} | {a} / {b} | {' '.join(fmt(x) for x in q)} | {fmt(statistics.median(q))} | "
                       f"{sum(x > 1 for x in q)} of {k} |")
    out.append("")
    sp, wh = runs.get((4, "split"), []), runs.get((4, "whole"), [])
    if sp and wh:
        k = min(len(sp), len(wh))
        faster = all(float(sp[i]["steps_per_second"]) > float(wh[i]["steps_per_second"]) for i in range(k))
        balanced = all(float(r["compute_imbalance"]) < 1.1 for r in sp)
        met = faster and balanced and 4 <= cores
        out.append(f"**Done-when 2** (4 ranks: split faster than whole in every round, compute imbalance under 1.1): "
                   f"{'met' if met else 'not met'} (faster in every round: {'yes' if faster else 'no'}; "
                   f"imbalance under 1.1 in every split run: {'yes' if balanced else 'no'}"
                   f"{'; oversubscribed, so not a measurement' if 4 > cores else ''}).\n")


def side_by_side(rows):
    """{N: [slowest set-up of each round]} from the control's rows (N rows per round)."""
    runs = {}
    for r in rows:
        m = re.fullmatch(r"side(\d+)", os.path.splitext(os.path.basename(r["path"]))[0])
        if m:
            runs.setdefault(int(m.group(1)), []).append(float(r.get("read_s") or 0) + float(r["setup_s"]))
    return {n: [max(v[i:i + n]) for i in range(0, len(v) - n + 1, n)] for n, v in runs.items()}


def weak_setup(rows, cores, out, side_rows=()):
    if not rows:
        return
    out.append("## Set-up at fixed work per rank\n")
    out.append("One chess500 container per rank (`tools/gen_weak_chess.py N`), `bench --steps 1`; "
               "set-up = reading the scene and building the Simulator, each on its slowest rank "
               "(bench's `read_s` + `setup_s`; the Simulator alone in the last column).\n")
    by, sim = {}, {}
    for r in rows:
        by.setdefault(int(r["ranks"]), []).append(float(r.get("read_s") or 0) + float(r["setup_s"]))
        sim.setdefault(int(r["ranks"]), []).append(float(r["setup_s"]))
    ranks = sorted(by)
    base = statistics.median(by[ranks[0]])
    out.append(f"| ranks | rounds | set-up s (median) | min - max | median / {ranks[0]} rank(s) | Simulator s (median) |")
    out.append("| ---: | ---: | ---: | --- | ---: | ---: |")
    for n in ranks:
        s = by[n]
        over = " (oversubscribed)" if n > cores else ""
        out.append(f"| {n}{over} | {len(s)} | {fmt(statistics.median(s))} | {fmt(min(s))} - {fmt(max(s))} | "
                   f"{fmt(statistics.median(s) / base)} | {fmt(statistics.median(sim[n]))} |")
    out.append("")
    last = ranks[-1]
    flat = statistics.median(by[last]) <= max(by[ranks[0]])
    real = last <= cores
    out.append(f"**Done-when 3** (set-up does not grow with the rank count: the median at {last} ranks no more than "
               f"the largest at {ranks[0]}): {'met' if flat and real else 'not met'} "
               f"({fmt(statistics.median(by[last]))} s against {fmt(base)} s, "
               f"{fmt(100 * (statistics.median(by[last]) / base - 1), 1)} %"
               f"{'; oversubscribed, so not a measurement' if not real else ''}).\n")
    side = side_by_side(side_rows)
    if not side or ranks[0] != 1:  # the control is measured against one rank alone
        return
    out.append(f"The control: N one-rank runs of one container at once, one per core, no MPI between them; "
               f"each round's slowest set-up. Growth over {ranks[0]} rank(s)' median ({fmt(base)} s): the node's "
               "is the control's, the code's is the rest.\n")
    out.append("| ranks | rounds | side by side s (median) | N ranks s (median) | the node's growth | the code's growth |")
    out.append("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in sorted(side):
        c = statistics.median(side[n])
        node = c - base
        if n in by:
            m = statistics.median(by[n])
            code = f"{fmt(m - c)} s ({fmt(100 * (m - c) / base, 1)} %)"
            mid = fmt(m)
        else:
            code, mid = "-", "-"
        out.append(f"| {n} | {len(side[n])} | {fmt(c)} | {mid} | {fmt(node)} s ({fmt(100 * node / base, 1)} %) | {code} |")
    out.append("")


def main():
    if len(sys.argv) not in (4, 5):
        sys.stderr.write(__doc__)
        sys.exit(2)
    cores = int(sys.argv[3])
    out = [f"# Issue 19 scaling check ({cores} cores)\n"]
    soft_floor(rows_of(sys.argv[1]), cores, out)
    weak_setup(rows_of(sys.argv[2]), cores, out, rows_of(sys.argv[4]) if len(sys.argv) == 5 else [])
    print("\n".join(out))


if __name__ == "__main__":
    main()
