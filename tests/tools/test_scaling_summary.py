#!/usr/bin/env python3
"""tools/scaling_summary.py on made-up runs whose medians, ratios and verdicts are known.

Usage: python3 test_scaling_summary.py TOOLS_DIR WORK_DIR. Exits 1 with the first
difference. Reference values, worked by hand from the rows below:
- soft floor, 4 ranks: split 120, 110, 130 steps/s against whole 100, 115, 105: ratios
  1.2, 0.957, 1.238 (median 1.2, 2 of 3 faster): Done-when 2 not met (round 2 slower);
  with round 2's split at 116, met; with an imbalance of 1.12 in one split run, not met.
- set-up: 1 rank 0.20 / 0.22 / 0.21 s (read_s 0.01 + setup_s), 8 ranks 0.21 / 0.23 /
  0.22 s: medians 0.21 and 0.22, the 8-rank median (0.22) = the largest one-rank
  set-up (0.22): met (+4.8 %); with the 8-rank runs 0.05 s slower (median 0.27), not
  met (+28.6 %).
- the control: 8 one-rank runs side by side, 3 rounds whose slowest set-ups are 0.22,
  0.23 and 0.21 s (the other seven runs 0.20 s): median 0.22 s, so the node's growth is
  0.22 - 0.21 = 0.010 s (4.8 % of one rank's 0.21) and, with the 8-rank median at 0.27,
  the code's is 0.27 - 0.22 = 0.050 s (23.8 %). No control file, or no one-rank runs:
  no control table.
"""
import csv
import os
import subprocess
import sys

HEADER = ["timestamp", "scene", "path", "ranks", "steps_per_second", "compute_imbalance", "cpu_imbalance",
          "rss_max_mib", "warmup", "steps", "setup_s", "read_s"]


def write(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=HEADER, restval="0")
        w.writeheader()
        for r in rows:
            w.writerow(r)


def floor_rows(split_sps, split_imb):
    rows = []
    for i in range(3):  # rounds: split, forces, whole in turn
        for v, sps, imb in (("split", split_sps[i], split_imb[i]), ("forces", 100.0, 1.05),
                            ("whole", [100.0, 115.0, 105.0][i], 1.2)):
            rows.append({"path": f"/x/soft_floor_{v}.yaml", "ranks": 4, "steps_per_second": sps,
                         "compute_imbalance": imb, "cpu_imbalance": imb, "rss_max_mib": 120, "warmup": 600,
                         "steps": 300})
    return rows


def setup_rows(extra):
    rows = []
    for i, (one, eight) in enumerate(zip([0.19, 0.21, 0.20], [0.20, 0.22, 0.21])):
        rows.append({"path": "/x/weak1.yaml", "ranks": 1, "setup_s": one, "read_s": 0.01})
        rows.append({"path": "/x/weak8.yaml", "ranks": 8, "setup_s": eight + extra, "read_s": 0.01})
    return rows


def side_rows():
    rows = []
    for slowest in (0.21, 0.22, 0.20):  # setup_s of the slowest; read_s 0.01 on every row
        for i in range(8):
            rows.append({"path": "/x/side8.yaml", "ranks": 1, "setup_s": slowest if i == 3 else 0.19, "read_s": 0.01})
    return rows


def summary(tools, work, floor, setup, cores=16, side=None):
    a, b, c = (os.path.join(work, n) for n in ("floor.csv", "setup.csv", "side.csv"))
    write(a, floor)
    write(b, setup)
    args = [sys.executable, os.path.join(tools, "scaling_summary.py"), a, b, str(cores)]
    if side is not None:
        write(c, side)
        args.append(c)
    return subprocess.run(args, check=True, capture_output=True, text=True).stdout


def expect(text, want):
    if want not in text:
        print(f"expected {want!r} in:\n{text}")
        sys.exit(1)


def main():
    tools, work = sys.argv[1], sys.argv[2]
    os.makedirs(work, exist_ok=True)
    s = summary(tools, work, floor_rows([120.0, 110.0, 130.0], [1.05, 1.06, 1.07]), setup_rows(0.0))
    expect(s, "| 4 | split | 3 | 120.0 | 1.060, 1.070 | 1.060 | 120.0 |")
    expect(s, "| 4 | split / whole | 1.200 0.957 1.238 | 1.200 | 2 of 3 |")
    expect(s, "**Done-when 2** (4 ranks: split faster than whole in every round, compute imbalance under 1.1): "
              "not met (faster in every round: no; imbalance under 1.1 in every split run: yes).")
    expect(s, "| 1 | 3 | 0.210 | 0.200 - 0.220 | 1.000 | 0.200 |")
    expect(s, "| 8 | 3 | 0.220 | 0.210 - 0.230 | 1.048 | 0.210 |")
    expect(s, ": met (0.220 s against 0.210 s, 4.8 %).")
    s = summary(tools, work, floor_rows([120.0, 116.0, 130.0], [1.05, 1.06, 1.07]), setup_rows(0.05))
    expect(s, "compute imbalance under 1.1): met (faster in every round: yes")
    expect(s, ": not met (0.270 s against 0.210 s, 28.6 %).")
    if "The control" in s:
        print(f"no control file, yet a control table:\n{s}")
        sys.exit(1)
    s = summary(tools, work, floor_rows([120.0, 116.0, 130.0], [1.05, 1.06, 1.07]), setup_rows(0.05), side=side_rows())
    expect(s, ": not met (0.270 s against 0.210 s, 28.6 %).")
    expect(s, "| 8 | 3 | 0.220 | 0.270 | 0.010 s (4.8 %) | 0.050 s (23.8 %) |")
    eight_only = [r for r in setup_rows(0.05) if r["ranks"] == 8]
    s = summary(tools, work, floor_rows([120.0, 116.0, 130.0], [1.05, 1.06, 1.07]), eight_only, side=side_rows())
    if "The control" in s:
        print(f"no one-rank runs to measure the control against, yet a control table:\n{s}")
        sys.exit(1)
    s = summary(tools, work, floor_rows([120.0, 116.0, 130.0], [1.05, 1.12, 1.07]), setup_rows(0.0))
    expect(s, "not met (faster in every round: yes; imbalance under 1.1 in every split run: no).")
    s = summary(tools, work, floor_rows([120.0, 116.0, 130.0], [1.05, 1.06, 1.07]), setup_rows(0.0), cores=2)
    expect(s, "| 4 (oversubscribed) | split |")
    expect(s, "not met (faster in every round: yes; imbalance under 1.1 in every split run: yes; oversubscribed")
    print("scaling_summary: all verdicts as worked by hand")


if __name__ == "__main__":
    main()
