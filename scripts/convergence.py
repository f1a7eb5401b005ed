"""Error against time for Tessera and Cycles, and how honest Tessera's error
estimate is. Run inside Blender, or with Blender as a Python module (`scripts/setup_bpy.sh 4.5.*`
prints the python of its venv; `$(scripts/setup_bpy.sh 4.5.*) scripts/convergence.py -- ...`; the plots need
matplotlib in that venv: `pip install matplotlib` with its pip):

    blender -b --factory-startup --python scripts/convergence.py -- \
        /work/shared/scenes/cornell_mcguire.blend [more .blend] [--width 160] \
        [--ladder 4 16 64 256] [--ref-samples 1024] [--bounce-ladder 0 1 2 4 8] [--bounce-samples 64] \
        [--adaptive-scenes veach_mis.blend modern_hall.blend] [--adaptive-budget-samples 64] \
        [--out docs/convergence]

For every scene: a high-sample reference per engine (same bounces as the
ladder, 8 unless --bounces), then a ladder of sample counts and, separately, of
max bounces, each render measured against its own engine's reference and the
other engine's. Per run: wall time of the whole render call (export/sync, BVH,
render; both engines alike), RMSE and relative MSE (mean of (x - r)^2 /
(r^2 + 0.01)); for Tessera also its own estimated relative error and the true
relative RMSE (RMSE / mean of the reference), whose ratio shows how honest the
estimate is. Efficiency = 1 / (MSE x time). The Tessera/Cycles efficiency
ratio is taken at Cycles' 64-sample error: the time Tessera needs for that MSE
(log-log interpolation along its ladder) against Cycles' time at 64 samples.
On the --adaptive-scenes, Tessera renders with the same time limit uniformly
and with adaptive sampling, and both are compared with the reference.

Writes OUT/convergence.csv, OUT/<scene>.png (log-log RMSE against time, both
engines) and OUT/README.md (tables and the command)."""

import argparse
import csv
import math
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("scenes", nargs="+")
ap.add_argument("--width", type=int, default=160)
ap.add_argument("--ladder", type=int, nargs="+", default=[4, 16, 64, 256])
ap.add_argument("--ref-samples", type=int, default=1024)
ap.add_argument("--bounces", type=int, default=8)
ap.add_argument("--runs", type=int, default=3,
                help="renders per point of the sample ladder (seeds 0..N-1, engines alternating): time = median wall "
                     "time, error = sqrt of the mean MSE over the seeds (one image's error swings with its rare bright "
                     "samples; efficiency is about the expected error)")
ap.add_argument("--bounce-ladder", type=int, nargs="+", default=[0, 1, 2, 4, 8])
ap.add_argument("--bounce-samples", type=int, default=64)
ap.add_argument("--adaptive-scenes", nargs="*", default=["veach_mis.blend", "modern_hall.blend"])
ap.add_argument("--adaptive-budget-samples", type=int, nargs="+", default=[64],
                help="time budgets = render time of a uniform Tessera render at these many samples")
ap.add_argument("--adaptive-threshold", type=float, nargs="+", default=[0.01])
ap.add_argument("--adaptive-min-samples", type=int, default=0)
ap.add_argument("--adaptive-seeds", type=int, default=1,
                help="renders per method (seeds 0..N-1); the table shows sqrt of their mean MSE")
ap.add_argument("--adaptive-only", action="store_true",
                help="only the adaptive/uniform comparison (Tessera reference only, no ladders)")
ap.add_argument("--adaptive-equal-samples", action="store_true",
                help="also render each adaptive run's mean samples per pixel uniformly (same seed): "
                     "the comparison at equal samples, which machine load does not move")
ap.add_argument("--adaptive-ladder-threshold", type=float, default=0.0,
                help="also render the sample ladder with adaptive sampling on in both engines at this noise "
                     "threshold (min samples automatic; the ladder's counts are the most a pixel gets), as users of "
                     "both render (Cycles' defaults: 0.01 for final renders, 0.1 in the viewport; at 0.01 few pixels "
                     "stop within 128 samples), and the efficiency at Cycles' adaptive 64-sample error; 0: not rendered")
ap.add_argument("--ref-cache", default="",
                help="with --adaptive-only: take Tessera's reference from this folder "
                     "(scripts/noise_at_equal_samples.py's cache, <scene>_TESSERA_<ref>_1000_<bounces>_<width>.npy) "
                     "when it is there")
ap.add_argument("--addon", default=os.path.join(HERE, "..", "addon"), help="folder holding the tessera add-on")
ap.add_argument("--out", default=os.path.join(HERE, "..", "docs", "convergence"))
args = ap.parse_args(argv)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
sys.path.insert(0, args.addon)
sys.path.insert(0, HERE)

import tessera  # noqa: E402
from helpers import render, set_size  # noqa: E402
from efficiency import cpu_name, time_for_mse  # noqa: E402

if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()
from tessera import engine  # noqa: E402

ENGINES = ("TESSERA", "CYCLES")
SHORT = {"TESSERA": "tessera", "CYCLES": "cycles"}
os.makedirs(args.out, exist_ok=True)


def load(path):
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    set_size(scene, args.width)
    return scene


def run(path, eng, samples, bounces, seed=0, adaptive_threshold=None, **tessera_settings):
    scene = load(path)
    for k, v in tessera_settings.items():
        setattr(scene.tessera, k, v)
    t0 = time.perf_counter()
    img = render(scene, eng, samples=samples, bounces=bounces, seed=seed,
                 adaptive_threshold=adaptive_threshold)[..., :3].astype(np.float64)
    wall = time.perf_counter() - t0
    st = dict(engine.last_render_stats) if eng == "TESSERA" else {}
    return img, wall, st


def metrics(img, ref):
    d2 = (img - ref) ** 2
    return {"rmse": float(np.sqrt(d2.mean())),
            "relmse": float((d2 / (ref ** 2 + 0.01)).mean()),
            "true_rel_error": float(np.sqrt(d2.mean()) / max(ref.mean(), 1e-12))}


def efficiency_at(tessera_rows, cycles_row):
    """Cycles' time for cycles_row over the time Tessera needs for the same MSE (own references), read off
    Tessera's ladder (efficiency.time_for_mse)."""
    if not cycles_row:
        return None
    t = time_for_mse([(r["rmse_own"] ** 2, r["seconds"]) for r in tessera_rows], cycles_row["rmse_own"] ** 2)
    return None if t is None else cycles_row["seconds"] / t


rows = []
summary = []
for path in args.scenes:
    name = os.path.basename(path)
    print(f"convergence: {name}", flush=True)
    refs = {}
    for eng in (("TESSERA",) if args.adaptive_only else ENGINES):
        cache = os.path.join(args.ref_cache, f"{name[:-6]}_{eng}_{args.ref_samples}_1000_{args.bounces}_{args.width}.npy")
        if args.adaptive_only and args.ref_cache and os.path.exists(cache):
            refs[eng] = np.load(cache)
            print(f"  reference {eng}: {cache}", flush=True)
            continue
        img, wall, st = run(path, eng, args.ref_samples, args.bounces, seed=1000)
        refs[eng] = img
        print(f"  reference {eng}: {args.ref_samples} samples, {wall:.1f} s", flush=True)
        rows.append(dict(scene=name, engine=eng, ladder="reference", samples=args.ref_samples, bounces=args.bounces,
                         seconds=wall, render_seconds=st.get("render_seconds", ""),
                         est_error=st.get("estimated_error", "")))

    def measured(eng, ladder, samples, bounces, runs, **extra):
        """One point from one or more renders [(img, wall, stats)] of different seeds: median time, RMSE from
        the mean MSE (the expected error), the estimate as mean estimate / RMS true error."""
        own_mse, other_mse, own_rel, walls, est, true_rel = [], [], [], [], [], []
        for img, wall, st in runs:
            own, other = metrics(img, refs[eng]), metrics(img, refs.get("CYCLES" if eng == "TESSERA" else "TESSERA", refs[eng]))
            own_mse.append(own["rmse"] ** 2), other_mse.append(other["rmse"] ** 2), own_rel.append(own["relmse"])
            walls.append(wall), true_rel.append(own["true_rel_error"])
            if "estimated_error" in st:
                est.append(st["estimated_error"])
        wall = float(np.median(walls))
        rmse = math.sqrt(float(np.mean(own_mse)))
        true_rms = math.sqrt(float(np.mean(np.square(true_rel))))
        st = runs[-1][2]
        row = dict(scene=name, engine=eng, ladder=ladder, samples=samples, bounces=bounces, seconds=wall,
                   render_seconds=st.get("render_seconds", ""), runs=len(runs),
                   seconds_min=min(walls), seconds_max=max(walls),
                   mean_samples=st.get("mean_samples", samples), rays=st.get("rays", ""),
                   rmse_own=rmse, relmse_own=float(np.mean(own_rel)), rmse_other=math.sqrt(float(np.mean(other_mse))),
                   efficiency_own=1.0 / (rmse ** 2 * wall), true_rel_error=true_rms,
                   est_error=float(np.mean(est)) if est else "",
                   est_over_true=float(np.mean(est)) / true_rms if est else "",
                   est_over_true_min=min(e / t for e, t in zip(est, true_rel)) if est else "",
                   est_over_true_max=max(e / t for e, t in zip(est, true_rel)) if est else "")
        row.update(extra)
        rows.append(row)
        print(f"  {ladder} {eng} spp={samples} bounces={bounces} x{len(runs)}: {wall:.2f} s (median), rmse own {rmse:.5f} "
              f"other {row['rmse_other']:.5f}" + (f", est/true {row['est_over_true']:.2f}" if est else ""), flush=True)
        return row

    def sample_ladder(label, adaptive_threshold=None):
        ladder = {e: [] for e in ENGINES}
        for spp in args.ladder:
            runs = {e: [] for e in ENGINES}
            for seed in range(args.runs):
                for eng in ENGINES if seed % 2 == 0 else ENGINES[::-1]:  # alternate so machine load hits both alike
                    runs[eng].append(run(path, eng, spp, args.bounces, seed=seed, adaptive_threshold=adaptive_threshold))
            for eng in ENGINES:
                ladder[eng].append(measured(eng, label, spp, args.bounces, runs[eng]))
        return ladder

    ladder_rows = {e: [] for e in ENGINES} if args.adaptive_only else sample_ladder("samples")
    adaptive_ladder_rows = ({e: [] for e in ENGINES} if args.adaptive_only or not args.adaptive_ladder_threshold
                            else sample_ladder("adaptive samples", args.adaptive_ladder_threshold))
    bounce_rows = {e: [] for e in ENGINES}
    for b in ([] if args.adaptive_only else args.bounce_ladder):
        for eng in ENGINES:
            bounce_rows[eng].append(measured(eng, "bounces", args.bounce_samples, b, [run(path, eng, args.bounce_samples, b)]))

    # Efficiency ratio at Cycles' 64-sample error (own references).
    c64 = next((r for r in ladder_rows["CYCLES"] if r["samples"] == 64), None)
    ratio = efficiency_at(ladder_rows["TESSERA"], c64)
    c64_adaptive = next((r for r in adaptive_ladder_rows["CYCLES"] if r["samples"] == 64), None)
    ratio_adaptive = efficiency_at(adaptive_ladder_rows["TESSERA"], c64_adaptive)

    # Adaptive against uniform, same time budget: the budget is the median
    # render time of 3 uniform renders at N samples; then per seed the methods
    # take turns (the order rotating), so load from other work hits all alike.
    adaptive = []
    if name in args.adaptive_scenes:
        for budget_spp in args.adaptive_budget_samples:
            budget = float(np.median([run(path, "TESSERA", budget_spp, args.bounces, seed=100 + k)[2]["render_seconds"]
                                      for k in range(3)]))
            methods = [("uniform", 0.0)] + [(f"adaptive {t}", t) for t in args.adaptive_threshold]
            runs = {label: [] for label, _ in methods}
            equal = {label: [] for label, _ in methods[1:]}
            for seed in range(args.adaptive_seeds):
                order = methods[seed % len(methods):] + methods[:seed % len(methods)]
                for label, thr in order:
                    img, wall, st = run(path, "TESSERA", 1_000_000, args.bounces, seed=seed, time_limit=budget,
                                        adaptive_threshold=thr, adaptive_min_samples=args.adaptive_min_samples)
                    runs[label].append(measured("TESSERA", label, 1_000_000, args.bounces, [(img, wall, st)],
                                                time_limit=budget, seed=seed))
                    if thr > 0 and args.adaptive_equal_samples:
                        # Uniform at the adaptive run's mean samples per pixel (same seed).
                        spp = max(1, round(st["mean_samples"]))
                        img_u, wall_u, st_u = run(path, "TESSERA", spp, args.bounces, seed=seed)
                        u = measured("TESSERA", f"uniform at {label}'s samples", spp, args.bounces,
                                     [(img_u, wall_u, st_u)], seed=seed)
                        equal[label].append((runs[label][-1]["rmse_own"], u["rmse_own"],
                                             st["mean_samples"], st_u["mean_samples"], st["rays"], st_u["rays"]))
            res = {}
            for label, rs in runs.items():
                res[label] = dict(rs[0], rmse_own=math.sqrt(sum(r["rmse_own"] ** 2 for r in rs) / len(rs)),
                                  rmse_median=float(np.median([r["rmse_own"] for r in rs])),
                                  mean_samples=sum(r["mean_samples"] for r in rs) / len(rs), runs=rs)
            u_runs = runs["uniform"]
            for t in args.adaptive_threshold:
                label = f"adaptive {t}"
                a_runs = runs[label]
                res[label]["seed_ratio_median"] = float(np.median(
                    [ar["rmse_own"] / ur["rmse_own"] for ar, ur in zip(a_runs, u_runs)]))
                res[label]["seed_wins"] = sum(ar["rmse_own"] < ur["rmse_own"] for ar, ur in zip(a_runs, u_runs))
                e = equal[label]
                if e:
                    res[label]["equal_ratio"] = math.sqrt(sum(x[0] ** 2 for x in e) / sum(x[1] ** 2 for x in e))
                    res[label]["equal_ratio_median"] = float(np.median([x[0] / x[1] for x in e]))
                    res[label]["equal_wins"] = sum(x[0] < x[1] for x in e)
                    # Rays per sample, adaptive over uniform: what a sample of the pixels adaptive
                    # sampling chose costs against an average one (a time budget buys fewer if > 1).
                    res[label]["equal_rays"] = float(np.median([(x[4] / x[2]) / (x[5] / x[3]) for x in e]))
                adaptive.append((budget, res["uniform"], res[label], budget_spp, t))

    summary.append(dict(name=name, ladder=ladder_rows, bounces=bounce_rows, ratio=ratio, c64=c64, adaptive=adaptive,
                        adaptive_ladder=adaptive_ladder_rows, ratio_adaptive=ratio_adaptive, c64_adaptive=c64_adaptive))

    try:
        if args.adaptive_only:
            raise ImportError
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for eng, color in (("TESSERA", "tab:blue"), ("CYCLES", "tab:red")):
            rs = ladder_rows[eng]
            t = [r["seconds"] for r in rs]
            axes[0].loglog(t, [r["rmse_own"] for r in rs], "o-", color=color, label=f"{eng.title()} vs own reference")
            axes[0].loglog(t, [r["rmse_other"] for r in rs], "x--", color=color, alpha=0.6,
                           label=f"{eng.title()} vs other's reference")
            for r in rs:
                axes[0].annotate(str(r["samples"]), (r["seconds"], r["rmse_own"]), fontsize=7)
            ra = adaptive_ladder_rows[eng]
            if ra:
                axes[0].loglog([r["seconds"] for r in ra], [r["rmse_own"] for r in ra], "^:", color=color,
                               label=f"{eng.title()} adaptive {args.adaptive_ladder_threshold} vs own reference")
            bs = bounce_rows[eng]
            axes[1].semilogy([r["bounces"] for r in bs], [r["rmse_own"] for r in bs], "o-", color=color,
                             label=f"{eng.title()} vs own reference")
            axes[1].semilogy([r["bounces"] for r in bs], [r["rmse_other"] for r in bs], "x--", color=color,
                             alpha=0.6, label=f"{eng.title()} vs other's reference")
        for a in adaptive:
            for r, m in ((a[1], "s"), (a[2], "*")):
                axes[0].loglog([r["seconds"]], [r["rmse_own"]], m, color="tab:green", markersize=9,
                               label=f"Tessera {r['ladder']}, {a[0]:.1f} s limit")
        axes[0].set_xlabel("wall time of the render call, s")
        axes[0].set_ylabel("RMSE")
        axes[0].set_title(f"{name}: samples {args.ladder}, {args.bounces} bounces")
        axes[0].legend(fontsize=7)
        axes[1].set_xlabel("max bounces")
        axes[1].set_ylabel("RMSE")
        axes[1].set_title(f"{args.bounce_samples} samples")
        axes[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(args.out, name.replace(".blend", ".png")), dpi=90)
        plt.close(fig)
    except ImportError:
        if not args.adaptive_only:
            print("convergence: matplotlib not importable; no plot (apt-get install python3-matplotlib)")

    # Write after every scene so a long run keeps what it has.
    keys = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    with open(os.path.join(args.out, "convergence.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)

    # Blender as a Python module (the bpy wheel, scripts/setup_bpy.sh) has no binary: its python runs the script.
    runner = ("blender -b --factory-startup --python" if bpy.app.binary_path
              else "$(scripts/setup_bpy.sh " + ".".join(bpy.app.version_string.split(".")[:2]) + ".*)")
    cmd = runner + " scripts/convergence.py -- " + " ".join(argv)
    cpu = cpu_name()
    lines = ["# Convergence: error against time, Tessera and Cycles", "",
             f"Blender {bpy.app.version_string}, {cpu}, {os.cpu_count()} cores, {time.strftime('%Y-%m-%d')}, width {args.width} px, "
             f"{args.bounces} max bounces, references {args.ref_samples} samples (seed 1000). Each point of the sample "
             f"ladder: {args.runs} renders per engine (seeds 0..{args.runs - 1}, the engines taking turns), time = their "
             "median wall time, RMSE = sqrt of their mean MSE (the expected error; one image's error swings with its "
             "rare bright samples). The bounce ladder: one render (seed 0) per point. Time is the "
             "wall time of the whole render call (sync/export, BVH, render, EXR write), so small sample counts "
             "are dominated by fixed costs, more so for Cycles. MSE against a reference includes the reference's "
             f"own noise (~ MSE(n) x n / {args.ref_samples}).", "",
             "Adaptive sampling under a time limit against uniform sampling with more seeds, at equal time and equal "
             "samples, and the error estimate on all shared scenes after its firefly term: `ADAPTIVE.md`.", "",
             "## Efficiency at Cycles' 64-sample error", "",
             "Tessera/Cycles = Cycles' time at 64 samples / the time Tessera needs for the same MSE against its own "
             "reference (= ratio of 1/(MSE x time) at equal MSE). Against its own reference each engine's error is its "
             "noise; the 'vs other' columns add the difference between the engines.", "",
             "| scene | Cycles 64 spp RMSE | Cycles 64 spp s | Tessera/Cycles efficiency | Tessera 64 spp RMSE own / vs Cycles ref | Cycles 64 spp RMSE vs Tessera ref |",
             "|---|---|---|---|---|---|"]
    for s in summary:
        t64 = next((r for r in s["ladder"]["TESSERA"] if r["samples"] == 64), None)
        if s["c64"] and t64:
            lines.append(f"| {s['name']} | {s['c64']['rmse_own']:.5f} | {s['c64']['seconds']:.2f} | "
                         f"{s['ratio']:.2f} | {t64['rmse_own']:.5f} / {t64['rmse_other']:.5f} | {s['c64']['rmse_other']:.5f} |")
    if args.adaptive_ladder_threshold:
        lines += ["", f"### Both engines with adaptive sampling (noise threshold {args.adaptive_ladder_threshold})", "",
                  "The same ladder with adaptive sampling on in both engines (min samples automatic; the ladder's "
                  "count is the most samples a pixel gets), as users of both render. Same efficiency "
                  "measure, at Cycles' adaptive 64-sample error. Mean samples: Tessera's, per pixel (Cycles does "
                  "not report its own).", "",
                  "| scene | Cycles RMSE | Cycles s | Tessera/Cycles efficiency | Tessera RMSE | Tessera s | Tessera mean spp |",
                  "|---|---|---|---|---|---|---|"]
        for s in summary:
            t64 = next((r for r in s["adaptive_ladder"]["TESSERA"] if r["samples"] == 64), None)
            if s["c64_adaptive"] and t64:
                lines.append(f"| {s['name']} | {s['c64_adaptive']['rmse_own']:.5f} | {s['c64_adaptive']['seconds']:.2f} | "
                             f"{s['ratio_adaptive']:.2f} | {t64['rmse_own']:.5f} | {t64['seconds']:.2f} | "
                             f"{t64['mean_samples']:.1f} |")
    lines += ["", "## Tessera's error estimate against the true error", "",
              "Estimated relative RMSE (`Film::estimated_relative_error`) over the true relative RMSE (RMSE / mean of "
              "Tessera's reference, which adds the reference's own noise): the mean estimate over the seeds against "
              "the RMS of their true errors, and in brackets the range of the per-seed ratios.", "",
              "| scene | " + " | ".join(f"{n} spp" for n in args.ladder) + " |",
              "|---|" + "---|" * len(args.ladder)]
    for s in summary:
        lines.append(f"| {s['name']} | " + " | ".join(
            f"{r['est_over_true']:.2f} ({r['est_over_true_min']:.2f}-{r['est_over_true_max']:.2f})"
            for r in s["ladder"]["TESSERA"]) + " |")
    lines += ["", "## Adaptive against uniform sampling at the same time budget (Tessera)", "",
              "Budget: the median render time of 3 uniform Tessera renders at N samples; every run gets it as time "
              "limit, the methods taking turns per seed. Adaptive: min samples "
              f"{args.adaptive_min_samples or 'automatic'}. RMSE against Tessera's reference: sqrt of the mean MSE "
              f"over {args.adaptive_seeds} seeds (0..{args.adaptive_seeds - 1}), and the median over seeds of the "
              "per-seed ratio adaptive/uniform (wins: seeds where adaptive's RMSE is lower). Equal samples: each "
              "adaptive run against a uniform render of the same seed at its mean samples per pixel (rounded), and the "
              "median ratio of their rays per sample.", "",
              "| scene | budget (N spp) | noise threshold | time limit s | uniform RMSE | adaptive RMSE | adaptive/uniform | "
              "median per-seed ratio (wins) | uniform mean spp | adaptive mean spp | equal samples: ratio, median per-seed (wins) | "
              "equal samples: rays per sample adaptive/uniform |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summary:
        for b, u, a, n, t in s["adaptive"]:
            eq = (f"{a['equal_ratio']:.2f}, {a['equal_ratio_median']:.2f} ({a['equal_wins']}/{args.adaptive_seeds}) | "
                  f"{a['equal_rays']:.2f}" if "equal_ratio" in a else "- | -")
            lines.append(f"| {s['name']} | {n} | {t} | {b:.2f} | {u['rmse_own']:.5f} | {a['rmse_own']:.5f} | "
                         f"{a['rmse_own'] / u['rmse_own']:.2f} | {a['seed_ratio_median']:.2f} "
                         f"({a['seed_wins']}/{args.adaptive_seeds}) | {u['mean_samples']:.1f} | {a['mean_samples']:.1f} | {eq} |")
    lines += ["", "## Runs", "",
              "| scene | engine | ladder | samples | bounces | runs | s (median; min-max) | RMSE own | relMSE own | RMSE vs other | 1/(MSE s) own |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summary:
        for part in ("ladder", "adaptive_ladder", "bounces"):
            for eng in ENGINES:
                for r in s[part][eng]:
                    spread = f"; {r['seconds_min']:.2f}-{r['seconds_max']:.2f}" if r.get("runs", 1) > 1 else ""
                    lines.append(f"| {s['name']} | {eng.title()} | {r['ladder']} | {r['samples']} | {r['bounces']} | "
                                 f"{r.get('runs', 1)} | {r['seconds']:.2f}{spread} | {r['rmse_own']:.5f} | {r['relmse_own']:.5f} | "
                                 f"{r['rmse_other']:.5f} | {r['efficiency_own']:.3g} |")
    lines += ["", "Plots: `<scene>.png` (left: RMSE against time over the sample ladder; right: RMSE against max "
              "bounces). All runs: `convergence.csv`.", "", "Command:", "", "```sh", cmd, "```", ""]
    with open(os.path.join(args.out, "README.md"), "w") as f:
        f.write("\n".join(lines))

print(open(os.path.join(args.out, "README.md")).read())
sys.stdout.flush()
os._exit(0)
