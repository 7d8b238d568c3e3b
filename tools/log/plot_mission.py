#!/usr/bin/python3
"""Draws a simulated mission from above: plot_mission.py SCENE.json OUT.png.

`thicket-log plot` (tools/log/plot.cc) reads the log and writes SCENE.json: the world's
cylinders and flight volume, the map's top-down projection (voxel columns, free or occupied),
the path, start, goal, the explorer's goals and the collisions, all in metres but the map columns
(voxel indices). This script only draws, with matplotlib as the benchmark's figures are drawn
(tools/bench/figures.py). The picture is `size` pixels square. Run it with /usr/bin/python3
(Debian's python3-matplotlib). Exit status 1 when the picture cannot be drawn, 2 for bad usage.
"""

import json
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Patch, Rectangle  # noqa: E402

FREE = "#c8e4fa"
OCCUPIED = "#464650"
OBSTACLE = "#deb887"
OBSTACLE_EDGE = "#8b5a2b"
BOUNDS = "#282828"
PATH = "#1450e6"
START = "#00aa3c"
GOAL = "#9614be"
EXPLORER_GOAL = "#ff8c00"
COLLISION = "#e60000"


def draw_map(ax, scene_map):
    """The map's columns as an image: free, occupied, unknown left transparent."""
    columns = [(i, j, 1) for i, j in scene_map["free"]] + [
        (i, j, 2) for i, j in scene_map["occupied"]
    ]
    if not columns:
        return
    voxel = scene_map["voxel_size"]
    i0 = min(c[0] for c in columns)
    j0 = min(c[1] for c in columns)
    i1 = max(c[0] for c in columns)
    j1 = max(c[1] for c in columns)
    grid = np.zeros((j1 - j0 + 1, i1 - i0 + 1))
    for i, j, cell in columns:
        grid[j - j0, i - i0] = cell
    masked = np.ma.masked_equal(grid, 0)
    ax.imshow(
        masked,
        origin="lower",
        extent=(i0 * voxel, (i1 + 1) * voxel, j0 * voxel, (j1 + 1) * voxel),
        cmap=ListedColormap([FREE, OCCUPIED]),
        vmin=1,
        vmax=2,
        interpolation="nearest",
        zorder=1,
    )


def as_points(value):
    """A list of [x, y] from a point, a list of points or null."""
    if not value:
        return []
    return value if isinstance(value[0], list) else [value]


def extent(scene):
    """The area shown [m]: the flight volume (else the map) and every point, with a margin."""
    xs, ys = [], []
    world = scene["world"]
    if world:
        xs += [world["bounds_min"][0], world["bounds_max"][0]]
        ys += [world["bounds_min"][1], world["bounds_max"][1]]
    elif scene["map"]:
        voxel = scene["map"]["voxel_size"]
        for i, j in scene["map"]["free"] + scene["map"]["occupied"]:
            xs += [i * voxel, (i + 1) * voxel]
            ys += [j * voxel, (j + 1) * voxel]
    points = scene["path"] + scene["explorer_goals"] + scene["collisions"]
    points += [p for p in (scene["start"], scene["goal"]) if p]
    xs += [p[0] for p in points]
    ys += [p[1] for p in points]
    if not xs:
        return (-1, 1), (-1, 1)
    pad = max(0.5, 0.03 * max(max(xs) - min(xs), max(ys) - min(ys)))
    return (min(xs) - pad, max(xs) + pad), (min(ys) - pad, max(ys) + pad)


def draw(scene, out):
    size = scene["size"]
    fig, ax = plt.subplots(figsize=(size / 100.0, size / 100.0), dpi=100)
    legend = []
    scene_map = scene["map"]
    if scene_map:
        draw_map(ax, scene_map)
        legend += [
            Patch(color=FREE, label="free (%s)" % scene_map["name"]),
            Patch(color=OCCUPIED, label="occupied (%s)" % scene_map["name"]),
            Patch(facecolor="white", edgecolor="#bbbbbb", label="unknown"),
        ]
    world = scene["world"]
    if world:
        for x, y, r in world["cylinders"]:
            ax.add_patch(
                Circle((x, y), r, facecolor=OBSTACLE, edgecolor=OBSTACLE_EDGE, alpha=0.8, zorder=2)
            )
        lo, hi = world["bounds_min"], world["bounds_max"]
        ax.add_patch(
            Rectangle(lo, hi[0] - lo[0], hi[1] - lo[1], fill=False, edgecolor=BOUNDS, zorder=3)
        )
        legend += [
            Patch(facecolor=OBSTACLE, edgecolor=OBSTACLE_EDGE, label="obstacle (SIM_WORLD)"),
            Patch(fill=False, edgecolor=BOUNDS, label="flight volume"),
        ]
    path = scene["path"]
    if path:
        ax.plot([p[0] for p in path], [p[1] for p in path], color=PATH, linewidth=2, zorder=4)
        ax.plot(*path[-1], marker="o", markersize=9, markerfacecolor="none", color=PATH, zorder=5)
        legend.append(
            Line2D([], [], color=PATH, label="path (estimate)" if scene["path_is_estimate"] else "path")
        )
    markers = [
        ("explorer_goals", "^", EXPLORER_GOAL, "explorer goal"),
        ("start", "o", START, "start"),
        ("goal", "D", GOAL, "goal"),
        ("collisions", "X", COLLISION, "collision"),
    ]
    for key, marker, color, label in markers:
        points = as_points(scene[key])
        if not points:
            continue
        ax.scatter(
            [p[0] for p in points],
            [p[1] for p in points],
            marker=marker,
            s=90,
            color=color,
            edgecolors="black",
            linewidths=0.6,
            zorder=6,
        )
        legend.append(
            Line2D([], [], linestyle="", marker=marker, color=color, markeredgecolor="black",
                   label=label)
        )
    (x0, x1), (y0, y1) = extent(scene)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(scene["title"] + ("\n" + scene["subtitle"] if scene["subtitle"] else ""),
                 fontsize=9)
    ax.grid(True, linewidth=0.3, alpha=0.5)
    if legend:
        ax.legend(handles=legend, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=4,
                  fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main(argv):
    if len(argv) != 3:
        sys.stderr.write("usage: plot_mission.py SCENE.json OUT.png\n")
        return 2
    with open(argv[1]) as f:
        scene = json.load(f)
    draw(scene, argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
