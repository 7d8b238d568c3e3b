#!/usr/bin/python3
"""Draws the benchmark report's figures: figures.py OUT_DIR.

Reads the tables that thicket-bench's report (tools/bench/report.cc) writes to OUT_DIR/figures/
and writes the PNG next to each; a figure whose table is absent is skipped. Every statistic (rates,
Wilson intervals, means) is computed in report.cc; this script only draws. Run it with
/usr/bin/python3 (Debian's python3-matplotlib). Exit status 1 when a figure could not be drawn,
2 for bad usage.
"""

import csv
import os
import re
import sys
import traceback

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

DPI = 150
SIZE = (7.0, 4.4)  # inches

# One colour and marker per method or variant, the same in every figure.
STYLE = {
    "none": ("#7f7f7f", "o"),
    "random": ("#ff7f0e", "s"),
    "rrt_star_optimistic": ("#d62728", "v"),
    "rrt_star_conservative": ("#9467bd", "^"),
    "nbvp": ("#8c564b", "D"),
    "local_exploration": ("#1f77b4", "o"),
    "frontier_memory": ("#e377c2", "*"),
    "local_exploration_look": ("#17becf", "P"),
    "local_exploration_reachable": ("#bcbd22", "X"),
    "frontier_memory_flat": ("#2ca02c", "h"),
    "frontier_memory_no_yaw": ("#000000", "d"),
    "frontier_memory_no_memory": ("#ff9896", "p"),
    "line": ("#7f7f7f", "s"),
    "gradient": ("#ff7f0e", "^"),
    "soft": ("#1f77b4", "o"),
}
LABEL = {
    "line": "straight-line goal finding",
    "gradient": "gradient goal finding",
    "soft": "gradient + soft goal",
}


def style(name, index):
    if name in STYLE:
        return STYLE[name]
    return ("C%d" % (index % 10), "x")


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def ordered_groups(rows, key):
    """Rows grouped by `key`, groups in the order they first appear."""
    groups = {}
    for row in rows:
        groups.setdefault(row[key], []).append(row)
    return groups


# The paper's methods and the one beyond it; any other variant of E2 is an ablation.
MAIN_METHODS = ["none", "random", "rrt_star_optimistic", "rrt_star_conservative", "nbvp",
                "local_exploration", "frontier_memory"]
# What an ablation is compared with, drawn beside the ablations.
ABLATION_REFERENCES = ["local_exploration", "frontier_memory"]


def success_vs_density(table, png, title):
    """Success rate vs density, one line per variant, with its Wilson 95 % interval: a band for
    up to three variants, else error bars side by side (six overlapping bands are unreadable).
    When the table has ablations as well as methods, two panels: the methods, then the ablations
    beside what they ablate."""
    groups = ordered_groups(read_csv(table), "variant")
    ablations = [v for v in groups if v not in MAIN_METHODS and v not in LABEL]
    if ablations and any(v in MAIN_METHODS for v in groups):
        panels = [("the paper's methods and frontier_memory",
                   {v: rows for v, rows in groups.items() if v in MAIN_METHODS}),
                  ("ablations",
                   {v: groups[v] for v in ABLATION_REFERENCES + ablations if v in groups})]
    else:
        panels = [(None, groups)]
    fig, axes = plt.subplots(1, len(panels), figsize=(SIZE[0] * len(panels), SIZE[1]),
                             squeeze=False)
    for ax, (subtitle, panel) in zip(axes[0], panels):
        success_panel(ax, panel)
        ax.set_title(title if subtitle is None else subtitle)
    if len(panels) > 1:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(png, dpi=DPI)
    plt.close(fig)


def success_panel(ax, groups):
    densities = sorted({float(r["density"]) for rows in groups.values() for r in rows})
    step = min((b - a for a, b in zip(densities, densities[1:])), default=0.05)
    bands = len(groups) <= 3
    for i, (variant, rows) in enumerate(groups.items()):
        rows.sort(key=lambda r: float(r["density"]))
        x = [float(r["density"]) for r in rows]
        rate = [float(r["rate"]) for r in rows]
        low = [float(r["low"]) for r in rows]
        high = [float(r["high"]) for r in rows]
        colour, marker = style(variant, i)
        label = LABEL.get(variant, variant)
        if bands:
            ax.plot(x, rate, color=colour, marker=marker, label=label)
            ax.fill_between(x, low, high, color=colour, alpha=0.15, linewidth=0)
        else:
            shift = step * 0.5 * (i - (len(groups) - 1) / 2) / len(groups)
            ax.errorbar([v + shift for v in x], rate,
                        yerr=[[r - lo for r, lo in zip(rate, low)],
                              [hi - r for r, hi in zip(rate, high)]],
                        color=colour, marker=marker, markersize=4, linewidth=1.2, elinewidth=0.8,
                        capsize=2, label=label)
    ax.set_xlabel("density [obstacles / m²]")
    ax.set_ylabel("success rate")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")


def e3_path_length(table, png):
    rows = read_csv(table)
    fig, ax = plt.subplots(figsize=SIZE)
    x = range(len(rows))
    width = 0.38
    for offset, method, column in ((-width / 2, "random", "random_mean_m"),
                                   (width / 2, "local_exploration", "local_exploration_mean_m")):
        ax.bar([i + offset for i in x], [float(r[column]) for r in rows], width,
               color=style(method, 0)[0], label=method)
    ax.set_xticks(list(x))
    ax.set_xticklabels(["%s\n(%s)" % (r["density"], r["pairs"]) for r in rows], fontsize=8)
    ax.set_xlabel("density [obstacles / m²] (worlds both solved)")
    ax.set_ylabel("mean path length [m]")
    ax.set_title("E3: path length on the worlds both methods solved")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=DPI)
    plt.close(fig)


def e4_success(table, png):
    """Bars per method, one per density, with the Wilson 95 % interval as error bars."""
    groups = ordered_groups(read_csv(table), "variant")
    densities = sorted({float(r["density"]) for rows in groups.values() for r in rows})
    fig, ax = plt.subplots(figsize=SIZE)
    width = 0.8 / len(densities)
    shades = ["#9ecae1", "#3182bd", "#08519c", "#c6dbef"]
    for j, density in enumerate(densities):
        xs, rates, below, above = [], [], [], []
        for i, rows in enumerate(groups.values()):
            for r in rows:
                if float(r["density"]) == density:
                    rate = float(r["rate"])
                    xs.append(i - 0.4 + width * (j + 0.5))
                    rates.append(rate)
                    below.append(rate - float(r["low"]))
                    above.append(float(r["high"]) - rate)
        ax.bar(xs, rates, width, yerr=[below, above], capsize=3, color=shades[j % len(shades)],
               label="density %g" % density)
    ax.set_xticks(range(len(groups)))
    ax.set_xticklabels(list(groups), rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("success rate")
    ax.set_ylim(0, 1.05)
    ax.set_title("E4: forest50, success per method")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=DPI)
    plt.close(fig)


def e4_forest(world_table, paths_table, out_dir, png):
    """Top-down: the world's cylinders, every method's path, start and goal."""
    world = read_csv(world_table)
    points = {r["kind"]: (float(r["x"]), float(r["y"])) for r in world if r["kind"] != "cylinder"}
    cylinders = [Circle((float(r["x"]), float(r["y"])), float(r["radius"]))
                 for r in world if r["kind"] == "cylinder"]
    fig, ax = plt.subplots(figsize=(7.0, 7.8))
    (x0, y0), (x1, y1) = points["bounds_min"], points["bounds_max"]
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="black"))
    ax.add_collection(PatchCollection(cylinders, facecolor="#4d7a3a", edgecolor="none"))
    paths = read_csv(paths_table)
    for i, row in enumerate(paths):
        samples = read_csv(os.path.join(out_dir, row["path"]))
        colour, _ = style(row["method"], i)
        xs = [float(s["x"]) for s in samples]
        ys = [float(s["y"]) for s in samples]
        ax.plot(xs, ys, color=colour, linewidth=1.4, label=row["method"])
        if xs:  # where the flight ended (at the goal or not)
            ax.plot(xs[-1], ys[-1], marker="x", color=colour, markersize=8, linestyle="none")
    ax.plot(*points["start"], marker="o", color="black", markersize=8, linestyle="none",
            label="start")
    ax.plot(*points["goal"], marker="*", color="gold", markeredgecolor="black", markersize=14,
            linestyle="none", label="goal")
    ax.set_xlim(x0 - 0.5, x1 + 0.5)
    ax.set_ylim(y0 - 0.5, y1 + 0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    seed = paths[0]["seed"] if paths else "?"
    density = paths[0]["density"] if paths else "?"
    ax.set_title("E4: density %s, seed %s, %d cylinders" % (density, seed, len(cylinders)))
    # Below the map, where it hides no tree.
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=4)
    fig.tight_layout()
    fig.savefig(png, dpi=DPI)
    plt.close(fig)


def e5_subsampling(table, png):
    """Gain error (mean, p95) and speed-up vs the fraction of frustum voxels checked."""
    rows = read_csv(table)
    rows.sort(key=lambda r: float(r["fraction"]))
    x = [float(r["fraction"]) for r in rows]
    fig, ax = plt.subplots(figsize=SIZE)
    ax.plot(x, [float(r["mean_abs_error"]) for r in rows], marker="o", color="#1f77b4",
            label="mean abs error")
    ax.plot(x, [float(r["p95_abs_error"]) for r in rows], marker="^", color="#1f77b4",
            linestyle="--", label="p95 abs error")
    ax.set_xscale("log")
    ax.set_xlabel("fraction of frustum voxels checked")
    ax.set_ylabel("gain error (fraction of unknown voxels)")
    ax.grid(True, which="both", alpha=0.3)
    speed = ax.twinx()
    speed.plot(x, [float(r["speedup"]) for r in rows], marker="s", color="#d62728",
               label="speed-up")
    speed.set_ylabel("speed-up vs all voxels")
    lines = ax.get_legend_handles_labels()
    more = speed.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], fontsize=8, loc="upper center",
              bbox_to_anchor=(0.5, -0.14), ncol=3)
    ax.set_title("E5: exploration-gain subsampling")
    fig.tight_layout()
    fig.savefig(png, dpi=DPI)
    plt.close(fig)


def main(argv):
    if len(argv) != 2 or argv[1] in ("-h", "--help"):
        print("usage: figures.py OUT_DIR (draws OUT_DIR/figures/*.png from their tables)",
              file=sys.stderr)
        return 2
    out_dir = argv[1]
    figures = os.path.join(out_dir, "figures")
    if not os.path.isdir(figures):
        print("figures.py: no folder %s" % figures, file=sys.stderr)
        return 2

    def at(name):
        return os.path.join(figures, name)

    jobs = [
        (["e1_success.csv"], "e1_success.png",
         lambda: success_vs_density(at("e1_success.csv"), at("e1_success.png"),
                                    "E1: optimization only, success vs density")),
        (["e3_path_length.csv"], "e3_path_length.png",
         lambda: e3_path_length(at("e3_path_length.csv"), at("e3_path_length.png"))),
        (["e4_success.csv"], "e4_success.png",
         lambda: e4_success(at("e4_success.csv"), at("e4_success.png"))),
        (["e4_forest_world.csv", "e4_forest_paths.csv"], "e4_forest.png",
         lambda: e4_forest(at("e4_forest_world.csv"), at("e4_forest_paths.csv"), out_dir,
                           at("e4_forest.png"))),
        (["e5_subsampling.csv"], "e5_subsampling.png",
         lambda: e5_subsampling(at("e5_subsampling.csv"), at("e5_subsampling.png"))),
    ]
    # E2, one figure per scenario: e2_success.csv is the paper world's, e2_success_<scenario>.csv
    # another's (report.cc, e2Figure).
    for name in sorted(os.listdir(figures)):
        match = re.fullmatch(r"e2_success(?:_(.+))?\.csv", name)
        if not match:
            continue
        scenario = match.group(1) or "paper"
        png = name[:-len(".csv")] + ".png"
        jobs.append(([name], png,
                     lambda name=name, png=png, scenario=scenario: success_vs_density(
                         at(name), at(png),
                         "E2 on %s: goal-selection strategies, success vs density" % scenario)))
    failed = 0
    for tables, png, draw in jobs:
        if not all(os.path.exists(at(t)) for t in tables):
            continue
        try:
            draw()
            print("wrote %s" % at(png))
        except Exception:  # one bad table should not cost the other figures
            failed += 1
            print("figures.py: cannot draw %s:" % png, file=sys.stderr)
            traceback.print_exc()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
