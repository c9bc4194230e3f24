"""The report of scripts/bench: per-group summaries against the targets, and OUT.md.

Split from scripts/bench (which imports it) to keep each file readable in one sitting.
"""
import math
import statistics

# The ray casters one binary picks from at run time (MEDIAREG_ACCEL; unset: Embree when
# libembree3.so.3 loads, else obvhs).
ACCELS = ["embree", "obvhs"]
# Targets the report states per group: (samples/s ratio, efficiency ratio) against the
# first Mitsuba variant (llvm_ad_rgb).
TARGETS = {"corpus": (1.3, 2.0)}
GROUP_TITLES = {"own": "Own scenes (mitsuba_scenes/)",
                "corpus": "Corpus scenes (public Mitsuba scenes, ../shared/corpus)"}


def simd(features):
    """The SIMD-relevant ones of target-feature names (rustc's or LLVM's spelling)."""
    return sorted(f for f in features
                  if f in ("sse4.2", "sse4_2", "avx", "avx2", "fma", "f16c", "bmi2")
                  or f.startswith("avx512"))


def accel_of(renderer):
    """The MEDIAREG_ACCEL a mediareg renderer runs with (None: unset, the default);
    `mediareg_embree_1thread` is the Embree one on one thread (scripts/cast_bound)."""
    for a in ACCELS:
        if renderer.removesuffix("_1thread") == f"mediareg_{a}":
            return a
    return None


def group_summaries(rows, m0):
    """Per group: each scene's median ratios against m0, their geometric mean, and how
    many scenes meet the group's targets (by the median, and in every pair)."""
    out = {}
    for g in GROUP_TITLES:
        grows = [r for r in rows if r["group"] == g]
        if not grows:
            continue
        res = {"scenes": [r["scene"] for r in grows]}
        for key in ["samples_per_second_ratio", "efficiency_ratio"]:
            sts = [r["pairs"][key].get(f"mediareg/{m0}") for r in grows]
            meds = [s["median"] for s in sts if s]
            res[key] = {"geometric_mean_of_medians":
                        math.exp(statistics.fmean(math.log(x) for x in meds))
                        if meds and min(meds) > 0 else None,
                        "min_median": min(meds) if meds else None,
                        "max_median": max(meds) if meds else None}
            if g in TARGETS:
                t = TARGETS[g][0 if key == "samples_per_second_ratio" else 1]
                res[key].update({"target": t,
                                 "scenes_median_at_target": sum(x >= t for x in meds),
                                 "scenes_every_pair_at_target":
                                 sum(bool(s) and s["min"] >= t for s in sts),
                                 "scenes": len(grows)})
        out[g] = res
    return out


def fmt(x, spec):
    return "n/a" if x is None else format(x, spec)


def rcell(st, spec=".2f", suffix="x"):
    """A ratio's median and [min, max] over the rounds' pairs."""
    if not st:
        return "–"
    return (f"{format(st['median'], spec)}{suffix} "
            f"[{format(st['min'], spec)}, {format(st['max'], spec)}]"
            + ("" if st["n"] > 1 else " (1 pair)"))


def pcell(st):
    """A cost as a percentage: median [min, max]."""
    if not st:
        return "–"
    return (f"{st['median'] * 100:+.0f}% [{st['min'] * 100:+.0f}%, "
            f"{st['max'] * 100:+.0f}%]")


def cpu_features_line(f):
    med = f["mediareg"]
    parts = [f"mediareg: {' '.join(simd(med['features'])) or 'unknown'} "
             f"({med['source']})"]
    mit = f["mitsuba"]
    dj = mit.get("drjit_llvm", {})
    if "cpu" in dj:
        parts.append(f"Mitsuba llvm_ad_rgb: Dr.Jit's LLVM {dj.get('llvm_version', '?')} "
                     f"JIT for target CPU `{dj['cpu']}`, {dj.get('vector_width', '?')}-wide "
                     f"vectors, {' '.join(simd(dj.get('features', []))) or 'no SIMD features'}")
    else:
        parts.append("Mitsuba llvm_ad_rgb: unknown ("
                     + (mit.get("error") or dj.get("error") or "no target reported") + ")")
    emb = mit.get("embree", {})
    if "version" in emb:
        parts.append(f"Mitsuba's ray casts: its bundled Embree {emb['version']}, "
                     f"{emb.get('kernels', 'unknown')} kernels")
    host = f["host"]
    if host:
        parts.append("host /proc/cpuinfo: " + " ".join(
            f"{k}{'' if v else ' (no)'}" for k, v in host.items()))
    return "; ".join(parts)


def markdown(rep):
    ms = rep["mitsuba_variants"]
    m0 = ms[0]
    rc = rep["mediareg"]["ray_caster"]
    lines = [f"# mediareg against Mitsuba 3 {rep['mitsuba_version']} (`scripts/bench`)", "",
             f"{rep['date']}, {rep['machine']['cpu']}, {rep['machine']['threads']} threads. "
             f"Own scenes at {rep['res']}x{rep['res']} px (one without a `res` parameter at "
             "its own size), corpus scenes as their reference was made (their parameters "
             f"and crop window); every render about {rep['seconds_target']:g} s (spp "
             f"calibrated per renderer), {rep['repeats']} interleaved rounds (reversed "
             "every other round), each render in its own process with the round's own "
             "seed. Seconds are the render's alone (Mitsuba after an untimed render at the "
             "same spp, so JIT compilation is not counted).", "",
             "Every ratio is taken within each round's pair of renders: the cell is the "
             "median over the rounds and [min, max].", "",
             f"mediareg: `{rep['mediareg']['version']}`; ray caster by default: "
             f"{rc['default']}"
             + "".join(f"; MEDIAREG_ACCEL={a}: {rc[a]}" for a in ACCELS if a in rc) + ".", "",
             "CPU features: " + cpu_features_line(rep["cpu_features"]) + ".", ""]

    def by_group(title, header, align, cells, keep=lambda row: True, note=None):
        lines.extend([title, ""] + ([note, ""] if note else []))
        for g, gtitle in GROUP_TITLES.items():
            grows = [r for r in rep["rows"] if r["group"] == g and keep(r)]
            if not grows:
                continue
            lines.extend([f"{gtitle}:", "", header, align])
            lines.extend(cells(r) for r in grows)
            lines.append("")

    # Summary per group, with the targets.
    lines += [f"## Summary against Mitsuba {m0}", ""]
    for g, s in rep["groups"].items():
        lines.append(f"- {GROUP_TITLES[g]}, {len(s['scenes'])} scenes:")
        for key, label in [("samples_per_second_ratio", "samples/s"),
                           ("efficiency_ratio", "efficiency")]:
            x = s[key]
            text = (f"  {label} ratio: geometric mean of the scenes' medians "
                    f"{fmt(x['geometric_mean_of_medians'], '.2f')}x, medians "
                    f"{fmt(x['min_median'], '.2f')}–{fmt(x['max_median'], '.2f')}x")
            if "target" in x:
                text += (f"; target >= {x['target']:g}x: met by the median on "
                         f"{x['scenes_median_at_target']} of {x['scenes']} scenes, in "
                         f"every pair on {x['scenes_every_pair_at_target']}")
            lines.append(text)
    lines.append("")

    def sps(row, key, a, b):
        return row["pairs"][key].get(f"{a}/{b}")

    by_group("## Throughput (M samples/s, median over rounds)",
             "| scene | px | mediareg | " + " | ".join(f"Mitsuba {m}" for m in ms) + " | "
             + " | ".join(f"ratio vs {m}" for m in ms) + " |",
             "|---|---:|" + "---:|" * (1 + 2 * len(ms)),
             lambda row: (f"| {row['scene']} | {row['size'][0]}x{row['size'][1]} | "
                          f"{row['summary']['mediareg']['samples_per_second'] / 1e6:.2f} | "
                          + " | ".join(f"{row['summary'][m]['samples_per_second'] / 1e6:.2f}"
                                       for m in ms) + " | "
                          + " | ".join(rcell(sps(row, "samples_per_second_ratio",
                                                 "mediareg", m)) for m in ms) + " |"))

    by_group("## Error at equal time and efficiency",
             "| scene | seconds | MSE mediareg | " + " | ".join(f"MSE {m}" for m in ms)
             + " | efficiency mediareg | "
             + " | ".join(f"efficiency ratio vs {m}" for m in ms) + " |",
             "|---|" + "---:|" * (3 + 2 * len(ms)),
             lambda row: (f"| {row['scene']} | "
                          + "/".join(f"{row['summary'][r]['seconds_median']:.1f}"
                                     for r in ["mediareg"] + ms)
                          + f" | {fmt(row['summary']['mediareg']['mse_mean'], '.3e')} | "
                          + " | ".join(fmt(row['summary'][m]['mse_mean'], '.3e') for m in ms)
                          + f" | {fmt(row['summary']['mediareg']['efficiency'], '.3g')} | "
                          + " | ".join(rcell(sps(row, "efficiency_ratio", "mediareg", m))
                                       for m in ms) + " |"),
             note="MSE: mean over rounds, against the Mitsuba 3 reference, minus the mean "
                  "variance of the reference (so it estimates the error against the true "
                  "image). Efficiency = 1 / (MSE x seconds), per render (the column: from "
                  "the mean MSE and mean seconds); the ratios per round. Seconds (median): "
                  "mediareg/" + "/".join(ms) + ".")

    def accel_cells(row):
        s = row["summary"]
        cells = [f"{s['mediareg']['samples_per_second'] / 1e6:.2f}"]
        for a in ACCELS:
            r = f"mediareg_{a}"
            cells.append(f"{s[r]['samples_per_second'] / 1e6:.2f}" if r in s else "–")
        for a in ACCELS:
            cells.append(rcell(sps(row, "samples_per_second_ratio", f"mediareg_{a}", m0)))
        cells.append(rcell(sps(row, "samples_per_second_ratio", "mediareg_embree",
                               "mediareg_obvhs")))
        for a in ACCELS:
            cells.append(rcell(sps(row, "efficiency_ratio", f"mediareg_{a}", m0)))
        return f"| {row['scene']} | " + " | ".join(cells) + " |"

    by_group(f"## Ray casters (M samples/s; scenes with triangle meshes)",
             f"| scene | mediareg default ({rc['default']}) | "
             + " | ".join(f"MEDIAREG_ACCEL={a}" for a in ACCELS) + " | "
             + " | ".join(f"{a} ratio vs {m0}" for a in ACCELS) + " | embree/obvhs | "
             + " | ".join(f"{a} efficiency ratio vs {m0}" for a in ACCELS) + " |",
             "|---|" + "---:|" * (2 + 3 * len(ACCELS)),
             accel_cells,
             keep=lambda row: any(accel_of(r) for r in row["summary"]),
             note="One binary, the ray caster chosen at run time by MEDIAREG_ACCEL (unset: "
                  "Embree when libembree3.so.3 loads, else obvhs); the default column is "
                  "the throughput table's mediareg.")

    by_group("## Cost of the albedo gradient (`--gradient albedo`)",
             "| scene | mediareg (M samples/s) | mediareg + gradient | gradient cost |",
             "|---|---:|---:|---:|",
             lambda row: (f"| {row['scene']} | "
                          f"{row['summary']['mediareg']['samples_per_second'] / 1e6:.2f} | "
                          f"{row['summary']['mediareg_gradient']['samples_per_second'] / 1e6:.2f}"
                          f" | {pcell(row['pairs']['gradient_cost'])} |"),
             keep=lambda row: "mediareg_gradient" in row["summary"],
             note="Cost: samples/s without the gradient over with it, minus 1, per round. "
                  "Scenes without a medium have no albedo to differentiate.")

    mems = ["mediareg"] + [f"mediareg_{a}" for a in ACCELS] + ms
    by_group("## Peak memory (RSS of the process, MiB, loading included)",
             "| scene | mediareg | " + " | ".join(f"MEDIAREG_ACCEL={a}" for a in ACCELS)
             + " | " + " | ".join(f"Mitsuba {m}" for m in ms) + " |",
             "|---|" + "---:|" * (1 + len(ACCELS) + len(ms)),
             lambda row: (f"| {row['scene']} | " + " | ".join(
                 f"{row['summary'][r]['peak_rss_mib']:.0f}" if r in row["summary"] else "–"
                 for r in mems) + " |"))

    by_group("## mediareg thread scaling (M samples/s)",
             f"| scene | 1 thread | {rep['machine']['threads']} threads | speed-up |",
             "|---|---:|---:|---:|",
             lambda row: (f"| {row['scene']} | "
                          f"{row['summary']['mediareg_1thread']['samples_per_second'] / 1e6:.2f}"
                          f" | {row['summary']['mediareg']['samples_per_second'] / 1e6:.2f} | "
                          f"{rcell(row['pairs']['thread_speedup'])} |"),
             note="Speed-up: samples/s on all threads over on 1, per round (the two "
                  "renders are adjacent in each round).")

    dropped = [f"{row['scene']}: {r} ({why})" for row in rep["rows"]
               for r, why in row["dropped"].items()]
    if dropped:
        lines += ["Not measured (failed in calibration): " + "; ".join(dropped) + ".", ""]
    corpus = [row for row in rep["rows"] if row["group"] == "corpus"]
    if corpus:
        lines += ["Corpus scenes: " + "; ".join(
            f"{row['scene']} ({row['covers'] or 'see ../shared/corpus/INDEX.md'}"
            + (", " + ", ".join(f"{k}={v}" for k, v in row["params"].items())
               if row["params"] else "")
            + (f", crop {','.join(map(str, row['crop']))}" if row["crop"] else "") + ")"
            for row in corpus) + ".", ""]
    lines += ["References: " + ", ".join(
        f"{row['scene']}: `{row['reference']['name']}` ({row['reference']['spp']} spp, "
        f"{row['reference']['variant']})" for row in rep["rows"]) + "."]
    return "\n".join(lines) + "\n"

