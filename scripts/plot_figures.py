#!/usr/bin/python3
"""PNG plots of the paper-figure data that gmm_mcl_figures writes.

usage: scripts/plot_figures.py DIR [DIR ...] [--dpi N]

In each DIR:
  nll_sweep.csv (+ nll_sweep.txt)        -> nll_sweep.png: paper Fig. 2, frame negative
      log-likelihood per pixel vs displacement along x, y, z and yaw; approximate (patch
      membership) and exact (all components) curves, and their difference
  sensitivity_summary.csv (+ sensitivity.txt, sensitivity_samples.csv) -> sensitivity.png:
      paper Fig. (convergence plots), log10 of the KL-divergence variance vs particle count N and
      vs component count M, with the mean KL
Needs matplotlib (Debian python3-matplotlib; run with /usr/bin/python3).
"""
import argparse
import csv
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_common import import_pyplot, to_float  # noqa: E402

AXES = ("x", "y", "z", "yaw")


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def read_meta(path):
    meta = {}
    if os.path.exists(path):
        with open(path) as f:
            for line in f:
                if "=" in line:
                    k, v = line.rstrip("\n").split("=", 1)
                    meta[k] = v
    return meta


def plot_nll_sweep(plt, directory, dpi):
    rows = read_csv(os.path.join(directory, "nll_sweep.csv"))
    meta = read_meta(os.path.join(directory, "nll_sweep.txt"))
    fig, axes = plt.subplots(2, 4, figsize=(16, 6.5), sharey="row",
                             gridspec_kw={"height_ratios": [3, 1.2]})
    for k, axis in enumerate(AXES):
        sel = sorted((r for r in rows if r["axis"] == axis), key=lambda r: to_float(r["offset"]))
        if not sel:
            continue
        unit = sel[0]["unit"]
        scale = 100.0 if unit == "m" else 180.0 / math.pi
        xlabel = "%s offset (%s)" % (axis, "cm" if unit == "m" else "deg")
        off = [to_float(r["offset"]) * scale for r in sel]
        apx = [to_float(r["approx_nll_per_px"]) for r in sel]
        ex = [to_float(r["exact_nll_per_px"]) for r in sel]
        ax = axes[0][k]
        ax.plot(off, ex, "-", color="black", lw=2.2, label="exact (all components)")
        ax.plot(off, apx, "--", color="tab:orange", lw=1.6, label="approximate (patch membership)")
        i = min(range(len(apx)), key=lambda j: apx[j])
        ax.plot(off[i], apx[i], "v", color="tab:orange", ms=7)
        ax.axvline(0.0, color="gray", lw=0.8, ls=":")
        ax.set_title(axis)
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.set_ylabel("NLL per pixel (nats)")
            ax.legend(fontsize=8, loc="upper center")
        axd = axes[1][k]
        diff = [a - e for a, e in zip(apx, ex)]
        if all(math.isfinite(d) for d in diff):
            axd.plot(off, diff, color="tab:red", lw=1.2)
        axd.axhline(0.0, color="gray", lw=0.8)
        axd.set_xlabel(xlabel)
        axd.grid(True, alpha=0.3)
        if k == 0:
            axd.set_ylabel("approx - exact\n(nats/px)")
    title = "Negative log-likelihood around the true pose"
    if meta:
        title += ": %s, frame %s, M=%s, %s px (stride %s)" % (
            meta.get("scene", "?"), meta.get("frame", "?"), meta.get("components", "?"),
            meta.get("pixels", "?"), meta.get("stride_px", "?"))
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    path = os.path.join(directory, "nll_sweep.png")
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plot_sensitivity(plt, directory, dpi):
    rows = read_csv(os.path.join(directory, "sensitivity_summary.csv"))
    meta = read_meta(os.path.join(directory, "sensitivity.txt"))
    sweeps = [s for s in ("particles", "components") if any(r["sweep"] == s for r in rows)]
    fig, axes = plt.subplots(1, max(1, len(sweeps)), figsize=(6.5 * max(1, len(sweeps)), 4.8),
                             squeeze=False)
    for k, sweep in enumerate(sweeps):
        ax = axes[0][k]
        sel = [r for r in rows if r["sweep"] == sweep and r["log10_variance_kl"] != ""]
        ref = [r for r in rows if r["sweep"] == sweep and r["log10_variance_kl"] == ""]
        sel.sort(key=lambda r: int(r["value"]))
        xs = [int(r["value"]) for r in sel]
        ax.semilogx(xs, [to_float(r["log10_variance_kl"]) for r in sel], "o-", color="tab:blue",
                    label="log10 Var(KL)")
        ax.set_xlabel("particles N" if sweep == "particles" else "components M")
        ax.set_ylabel("log10 variance of KL divergence", color="tab:blue")
        ax.grid(True, which="both", alpha=0.3)
        ax2 = ax.twinx()
        ax2.semilogx(xs, [to_float(r["mean_kl"]) for r in sel], "s--", color="tab:gray", ms=4,
                     label="mean KL")
        ax2.set_yscale("log")
        ax2.set_ylabel("mean KL (nats)", color="tab:gray")
        if ref:
            refv = int(ref[0]["value"])
            ax.axvline(refv, color="tab:red", ls=":", lw=1)
            ax.text(refv, ax.get_ylim()[1], " reference\n %s" % refv, color="tab:red", fontsize=8,
                    va="top", ha="right")
        ref_value = ref[0]["value"] if ref else "?"
        if sweep == "particles":
            title = "vs particle count (reference N=%s)" % meta.get("reference_particles", ref_value)
        else:
            title = "vs component count (reference M=%s, N=%s; runs N=%s)" % (
                meta.get("reference_components", ref_value),
                meta.get("component_reference_particles", "?"),
                meta.get("component_particles", "?"))
        ax.set_title(title, fontsize=10)
    if meta:
        fig.suptitle("KL-divergence variance against a reference filter\n%s, %s runs, frames %s..%s, "
                     "stride %s, %s init" % (meta.get("scene", "?"), meta.get("runs", "?"),
                                             meta.get("eval_from", "?"),
                                             int(meta.get("frames", "0")) - 1,
                                             meta.get("stride_px", "?"), meta.get("init", "?")),
                     fontsize=10)
    fig.tight_layout()
    path = os.path.join(directory, "sensitivity.png")
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--dpi", type=int, default=110)
    args = ap.parse_args(argv)
    plt = import_pyplot("plot_figures")
    if plt is None:
        return 3
    written = []
    for d in args.dirs:
        if os.path.exists(os.path.join(d, "nll_sweep.csv")):
            written.append(plot_nll_sweep(plt, d, args.dpi))
        if os.path.exists(os.path.join(d, "sensitivity_summary.csv")):
            written.append(plot_sensitivity(plt, d, args.dpi))
    if not written:
        print("plot_figures: no nll_sweep.csv or sensitivity_summary.csv in %s" % " ".join(args.dirs),
              file=sys.stderr)
        return 1
    print("wrote " + ", ".join(written))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
