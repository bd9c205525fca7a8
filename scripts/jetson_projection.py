#!/usr/bin/env python3
"""Projects the CUDA kernels of one update to the Jetsons from Nsight Compute counters.

Reads the raw-page CSVs that `GPU_CHECK_STEPS=ncu scripts/gpu_check.sh` writes (ncu_WORKLOAD.csv,
one row per kernel launch) on the machine where they were measured (an H100 or H200), and prints
per kernel and per update: the measured time, the work counted (warp instructions per pipe,
DRAM and L2 bytes), which resource bounds the kernel on the measuring GPU and how close it ran to
that bound, and the time each Jetson would take at the same fraction of its own bound.

    scripts/jetson_projection.py build-gpu/logs/ncu_paper.csv build-gpu/logs/ncu_cpu.csv
    scripts/jetson_projection.py --flops ncu_paper.csv     # the measured FP32 rate per kernel

The model and its assumptions are written out in docs/tx2.md ("What the Jetsons would run").
"""
import argparse
import csv
import os
import sys

# Per streaming multiprocessor and clock: FP32 lanes, INT32 lanes (Pascal runs integer work on the
# FP32 cores, so both draw on one budget there), special-function (MUFU: exp, log, rsqrt) lanes,
# load/store lanes, warp instructions issued. From the CUDA C++ Programming Guide's table of
# arithmetic instruction throughput (results per clock per multiprocessor) by compute capability.
# Clocks, SM counts and memory bandwidths are the data sheets' maxima (MAXN power modes).
TARGETS = {
    # name: (compute capability, SMs, GPU clock GHz, DRAM GB/s, FP32, INT32, shared FP32/INT, MUFU, LSU, issue)
    "TX2": ("6.2", 2, 1.30, 59.7, 128, 128, True, 32, 32, 4),
    "Orin NX 16GB": ("8.7", 8, 0.918, 102.4, 128, 64, False, 16, 32, 4),
    "Orin Nano 8GB": ("8.7", 8, 0.625, 68.0, 128, 64, False, 16, 32, 4),
    "Orin Nano 8GB Super": ("8.7", 8, 1.02, 102.0, 128, 64, False, 16, 32, 4),
}
# The measuring GPU (Hopper, compute capability 9.0): the SM count and clock come from the
# counters; DRAM bandwidth by name.
HOPPER = {"FP32": 128, "INT32": 64, "MUFU": 16, "LSU": 32, "issue": 4}
HOPPER_DRAM_GBS = {"H100": 3350.0, "H200": 4800.0}
LATENCY_ETA = 0.3

UNIT_SCALE = {"ns": 1e-9, "nsecond": 1e-9, "us": 1e-6, "usecond": 1e-6, "ms": 1e-3,
              "msecond": 1e-3, "s": 1.0, "second": 1.0, "byte": 1.0, "kbyte": 1e3,
              "mbyte": 1e6, "gbyte": 1e9, "cycle/nsecond": 1e9, "cycle/usecond": 1e6,
              "cycle/second": 1.0, "hz": 1.0, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}


def read_raw(path):
    """Kernel launches of one raw-page CSV: a list of (id, short name, {metric: value})."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f)]
    start = next((i for i, r in enumerate(rows) if r and r[0] == "ID"), None)
    if start is None:
        sys.exit(f"{path}: no ncu raw-page header (a row starting with \"ID\")")
    header, units = rows[start], rows[start + 1]
    launches = []
    for r in rows[start + 2:]:
        if len(r) != len(header):
            continue
        m = {}
        for h, u, v in zip(header, units, r):
            try:
                m[h] = float(v.replace(",", "")) * UNIT_SCALE.get(u.strip().lower(), 1.0)
            except ValueError:
                m[h] = v
        name = str(m.get("Kernel Name", "?")).split("(")[0].split("<")[0].split("::")[-1]
        launches.append((m.get("ID"), name, m))
    return launches


def get(m, key, default=0.0):
    v = m.get(key, default)
    return v if isinstance(v, float) else default


def work(m):
    """Warp instructions per pipe and bytes of one launch."""
    return {
        "inst": get(m, "smsp__inst_executed.sum") or get(m, "sm__inst_executed.sum"),
        "fma": get(m, "smsp__inst_executed_pipe_fma.sum"),
        "alu": get(m, "smsp__inst_executed_pipe_alu.sum"),
        "fp16": get(m, "smsp__inst_executed_pipe_fp16.sum"),
        "xu": get(m, "smsp__inst_executed_pipe_xu.sum"),
        "lsu": get(m, "smsp__inst_executed_pipe_lsu.sum"),
        "dram": get(m, "dram__bytes_read.sum") + get(m, "dram__bytes_write.sum"),
        "l2": get(m, "lts__t_bytes.sum"),
    }


def bounds(w, fp32, int32, shared, mufu, lsu, issue, sms, clock_hz, dram_gbs, bytes_key):
    """Seconds each resource needs for the work at full rate, spread evenly over the SMs."""
    per_sm = 1.0 / (sms * clock_hz)
    if shared:  # Pascal: FP32 and integer instructions on the same cores
        core = 32.0 * (w["fma"] + w["alu"] + w["fp16"]) / fp32
    else:
        core = max(32.0 * (w["fma"] + w["alu"]) / fp32, 32.0 * w["alu"] / int32)
    return {
        "core": core * per_sm,
        "mufu": 32.0 * w["xu"] / mufu * per_sm,
        "lsu": 32.0 * w["lsu"] / lsu * per_sm,
        "issue": w["inst"] / issue * per_sm,
        "dram": w[bytes_key] / (dram_gbs * 1e9),
    }


def gpu_name(launches):
    for _, _, m in launches:
        d = str(m.get("Device", m.get("device__attribute_display_name", "")))
        for k in HOPPER_DRAM_GBS:
            if k in d:
                return k
    return os.environ.get("GMM_MCL_NCU_GPU", "H100")


def one_update(launches):
    """The first launch of each kernel name: one update of the benchmark."""
    seen, out = set(), []
    for lid, name, m in launches:
        if name not in seen:
            seen.add(name)
            out.append((lid, name, m))
    return out


def flops(m):
    """FP32 operations executed: an FFMA counts 2, FADD and FMUL 1."""
    return (2 * get(m, "sm__sass_thread_inst_executed_op_ffma_pred_on.sum")
            + get(m, "sm__sass_thread_inst_executed_op_fadd_pred_on.sum")
            + get(m, "sm__sass_thread_inst_executed_op_fmul_pred_on.sum"))


def flops_lines(path, workload):
    for lid, name, m in read_raw(path):
        t = get(m, "gpu__time_duration.sum")
        f = flops(m)
        clk = get(m, "sm__cycles_elapsed.avg.per_second")
        sms = get(m, "device__attribute_multiprocessor_count", 132.0)
        peak = 2 * 128 * sms * clk
        if t <= 0 or clk <= 0:
            continue
        print(f"{workload} {name}: {t * 1e6:.1f} us, "
              f"{get(m, 'launch__registers_per_thread'):.0f} registers, "
              f"issue active {get(m, 'smsp__issue_active.avg.pct_of_peak_sustained_active'):.1f}%, "
              f"warps active {get(m, 'sm__warps_active.avg.pct_of_peak_sustained_active'):.1f}%, "
              f"threads/inst {get(m, 'smsp__thread_inst_executed_per_inst_executed.ratio'):.1f}, "
              f"FP32 FLOP executed {f:.3e} = {f / t * 1e-12:.2f} TFLOP/s = "
              f"{100 * f / t / peak:.1f}% of peak at {clk * 1e-9:.2f} GHz, "
              f"DRAM read {get(m, 'dram__bytes_read.sum') * 1e-6:.1f} MB write "
              f"{get(m, 'dram__bytes_write.sum') * 1e-6:.1f} MB, "
              f"shared bank conflicts {get(m, 'l1tex__data_bank_conflicts_pipe_lsu_mem_shared.sum'):.3g}")


def project(path, workload, launch_us):
    launches = read_raw(path)
    gpu = gpu_name(launches)
    update = one_update(launches)
    print(f"\n### {workload}: one update, measured on an {gpu} ({len(update)} kernels)\n")
    names = list(TARGETS)
    print("| kernel | " + gpu + " us | FP32 GFLOP | warp inst (fma / alu / mufu / lsu) | DRAM / L2 MB | "
          "bound on the " + gpu + " | fraction of it reached | " +
          " | ".join(f"{n} us" for n in names) + " |")
    print("|---|---|---|---|---|---|---|" + "---|" * len(names))
    total_h, total = 0.0, {n: [0.0, 0.0] for n in names}
    for _, name, m in update:
        t = get(m, "gpu__time_duration.sum")
        clk = get(m, "sm__cycles_elapsed.avg.per_second")
        sms = get(m, "device__attribute_multiprocessor_count", 132.0)
        if t <= 0 or clk <= 0:
            continue
        w = work(m)
        name = f"{name} ({get(m, 'launch__grid_size'):.0f} x {get(m, 'launch__block_size'):.0f})"
        bh = bounds(w, HOPPER["FP32"], HOPPER["INT32"], False, HOPPER["MUFU"], HOPPER["LSU"],
                    HOPPER["issue"], sms, clk, HOPPER_DRAM_GBS[gpu], "dram")
        limiter = max(bh, key=bh.get)
        eta = bh[limiter] / t
        # A kernel that reached less than 30% of its bound on the measuring GPU was held by
        # latency (launch, ramp-up, dependent steps), not by a rate: on a Jetson it takes the
        # larger of that time scaled by the clocks and its work at 30% of the Jetson's rates.
        latency_bound = eta < LATENCY_ETA
        total_h += t
        cells = []
        for n in names:
            cc, tsms, ghz, gbs, fp32, int32, shared, mufu, lsu, issue = TARGETS[n]
            e = max(eta, LATENCY_ETA)
            lo = max(bounds(w, fp32, int32, shared, mufu, lsu, issue, tsms, ghz * 1e9, gbs,
                            "dram").values()) / e
            hi = max(bounds(w, fp32, int32, shared, mufu, lsu, issue, tsms, ghz * 1e9, gbs,
                            "l2").values()) / e
            if latency_bound:
                lo, hi = max(lo, t * clk / (ghz * 1e9)), max(hi, t * clk / (ghz * 1e9))
            lo += launch_us * 1e-6
            hi += launch_us * 1e-6
            total[n][0] += lo
            total[n][1] += hi
            a, b = f"{lo * 1e6:,.0f}", f"{hi * 1e6:,.0f}"
            cells.append(a if a == b else f"{a}-{b}")
        print(f"| {name} | {t * 1e6:.1f} | {flops(m) * 1e-9:.3g} | {w['fma']:.3g} / {w['alu']:.3g} / {w['xu']:.3g} / "
              f"{w['lsu']:.3g} | {w['dram'] * 1e-6:.1f} / {w['l2'] * 1e-6:.1f} | {limiter} | "
              f"{100 * eta:.0f}%{' (latency)' if latency_bound else ''} | " + " | ".join(cells) + " |")
    cells = []
    for n in names:
        lo, hi = total[n]
        ms = [f"{lo * 1e3:.1f}", f"{hi * 1e3:.1f}"]
        rate = [f"{1 / hi:,.0f}", f"{1 / lo:,.0f}"]
        cells.append("**" + (ms[0] if ms[0] == ms[1] else "-".join(ms)) + " ms (" +
                     (rate[0] if rate[0] == rate[1] else "-".join(rate)) + "/s)**")
    print(f"| all kernels | {total_h * 1e6:.1f} ({1 / total_h:,.0f}/s) | | | | | | " +
          " | ".join(cells) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("csv", nargs="+", help="ncu raw-page CSVs (ncu_WORKLOAD.csv)")
    ap.add_argument("--flops", action="store_true", help="print the measured FP32 rates only")
    ap.add_argument("--launch-us", type=float, default=0.0,
                    help="time added per kernel launch on the Jetsons (default 0: launches "
                    "overlap the previous kernel)")
    args = ap.parse_args()
    for path in args.csv:
        workload = os.path.basename(path).rsplit(".", 1)[0].replace("ncu_", "")
        if args.flops:
            flops_lines(path, workload)
        else:
            project(path, workload, args.launch_us)


if __name__ == "__main__":
    main()
