#!/usr/bin/python3
"""The paper's Fig. 6 from a per-step CSV of `softcontact bench --per-step`.

Plots the contact response time of each step against its colliding points, with the
least-squares line t = a + b n, and prints the fit (slope b in ns per collision, R^2).
A second panel shows the colliding points against simulated time (the pile growing).

On a shared machine some steps lose whole scheduler ticks (multiples of 4 ms) to other
processes; they lie far above the band of the others and pull a plain least-squares
line up. So two fits are reported: least squares over all steps, and the same after
dropping the steps more than 3 robust standard deviations (1.4826 MAD of the residuals)
above the line, repeated until no more steps are dropped (one-sided: losing the CPU only
ever adds time). The plot draws both.

Usage: /usr/bin/python3 tools/plot_fig6.py [STEPS.csv] [--out PNG] [--column response_ms]
defaults: output/bench/fig6_chess500.csv -> docs/images/fig6_chess500.png
(`python3` on PATH may lack matplotlib; /usr/bin/python3 is Debian's, with python3-matplotlib.)
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_columns(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"plot_fig6: {path}: no rows")
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def fit_line(x, y):
    """Least squares y = a + b x; returns a, b and R^2."""
    A = np.column_stack([np.ones_like(x), x])
    (a, b), *_ = np.linalg.lstsq(A, y, rcond=None)
    res = y - (a + b * x)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(res**2)) / ss_tot if ss_tot > 0 else float("nan")
    return float(a), float(b), r2


def trimmed_fit(x, y, k=3.0, rounds=20):
    """Least squares after iteratively dropping points more than k robust standard
    deviations (1.4826 * median absolute deviation of the residuals) above the line.
    Returns a, b, R^2 over the kept points, and the mask of kept points."""
    keep = np.ones_like(x, dtype=bool)
    for _ in range(rounds):
        a, b, _ = fit_line(x[keep], y[keep])
        r = y - (a + b * x)
        mad = np.median(np.abs(r[keep] - np.median(r[keep])))
        new = r <= k * 1.4826 * mad if mad > 0 else keep
        if np.array_equal(new, keep):
            break
        keep = new
    a, b, r2 = fit_line(x[keep], y[keep])
    return a, b, r2, keep


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("csv", nargs="?", default=os.path.join(root, "output/bench/fig6_chess500.csv"))
    p.add_argument("--out", default=os.path.join(root, "docs/images/fig6_chess500.png"))
    p.add_argument("--column", default="response_ms", help="time column to plot (default response_ms)")
    p.add_argument("--title", default=None)
    args = p.parse_args()

    c = read_columns(args.csv)
    for k in ("collisions", args.column, "time"):
        if k not in c:
            sys.exit(f"plot_fig6: {args.csv}: no column '{k}'")
    n, t_ms, time = c["collisions"], c[args.column], c["time"]
    a, b, r2 = fit_line(n, t_ms)
    ns_per_collision = b * 1e6  # ms -> ns
    ta, tb, tr2, keep = trimmed_fit(n, t_ms)
    name = os.path.splitext(os.path.basename(args.csv))[0]

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [3, 2]})
    ax.scatter(n[keep], t_ms[keep], s=5, alpha=0.4, color="tab:blue", label=f"{int(keep.sum())} steps")
    ax.scatter(n[~keep], t_ms[~keep], s=5, alpha=0.4, color="tab:gray",
               label=f"{int((~keep).sum())} steps > 3 robust sd above the line")
    xs = np.linspace(0, n.max() if n.size else 1, 100)
    ax.plot(xs, ta + tb * xs, color="tab:red",
            label=f"fit without them: {ta * 1e3:.0f} us + {tb * 1e6:.0f} ns x n  (R$^2$ = {tr2:.3f})")
    ax.plot(xs, a + b * xs, color="tab:orange", ls="--",
            label=f"least squares, all steps: {a * 1e3:.0f} us + {ns_per_collision:.0f} ns x n  (R$^2$ = {r2:.3f})")
    ax.set_xlabel("colliding points n")
    ax.set_ylabel("contact response [ms]" if args.column == "response_ms" else args.column)
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=9)
    ax.set_title(args.title or f"Fig. 6: contact response time per step ({name})", fontsize=10)

    ax2.plot(time, n, color="tab:green", lw=1)
    ax2.set_xlabel("simulated time [s]")
    ax2.set_ylabel("colliding points")
    ax2.grid(alpha=0.3)
    ax2.set_title("colliding points per step", fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    fig.savefig(args.out, dpi=110)

    print(f"{args.csv}: {len(n)} steps, colliding points {int(n.min())} to {int(n.max())}")
    print(f"least squares over all steps, {args.column} = a + b n: a = {a * 1e3:.1f} us, "
          f"b = {ns_per_collision:.1f} ns per collision, R^2 = {r2:.4f}")
    print(f"without the {int((~keep).sum())} steps > 3 robust sd above the line: a = {ta * 1e3:.1f} us, "
          f"b = {tb * 1e6:.1f} ns per collision, R^2 = {tr2:.4f}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
