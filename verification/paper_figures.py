#!/usr/bin/env python3
"""PNG counterparts of the paper's figures (Schäfer et al. 2024, Figs. 4,
6, 8, 9, 10, 11 and the deformation modes of Section 5.3) from the run
folders of the shipped cases, made by one command:

    verification/.venv/bin/python verification/paper_figures.py \
        --runs DIR --out docs/figures [--windows windows.json]

DIR holds one run folder per case, DIR/<case>/, as
`full_validation.py --keep DIR` leaves them (and `ncform run
cases/<case>.toml --out DIR/<case>` for the OATs): hemisphere-0,
hemisphere-45, hemisphere-0-90, tetrahedron-0, tetrahedron-45,
tetrahedron-90, oat30, oat45, oat60 (oat45-explicit is drawn too in the
OAT curves when present). A figure whose runs are all absent is skipped
with a note; a run folder that lacks a file a figure needs stops the
script with a message naming the file.

The die's opening is computed from the case files in cases/ (the run folder
does not record the tools' dimensions), so a run of an edited case is drawn
with the shipped case's opening.

`--windows JSON`: extra evaluation windows drawn on the strain maps, a
list of {"name": "D", "centre": [x, y], "size": [w, h]} in reference
coordinates of the blank [mm] (optionally "cases": ["hemisphere-0", ...]
to draw a window on those runs only), mapped to the current positions as
the material moves, like the cases' [[zone]] windows (docs/forming.md,
"Zones").

What each file shows: docs/figures/README.md. The strain measures are
the paper's (Section 4; docs/cases.md, "Outputs"): γ = I10 [deg],
E22 = I8 − 1, E⊥ = I11 − 1. The maps of the formed plies are seen from
below, as the paper's 2D image correlation through the transparent die
(Section 5.1): the x–y projection of the current positions, mirrored
(x grows to the left), the lowest material drawn last, as ncform's own
`maps/` (docs/forming.md, "Outputs").
"""

import argparse
import functools
import io
import json
import os
import sys
import tomllib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.tri as mtri  # noqa: E402
from matplotlib import patheffects  # noqa: E402
from matplotlib.colors import (ListedColormap, BoundaryNorm, Normalize, SymLogNorm,  # noqa: E402
                               TwoSlopeNorm)
from matplotlib.patches import Patch  # noqa: E402
import meshio  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

import findings  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CASES = os.path.join(REPO, "cases")

DPI = 110
OAT_CASES = [("oat30", "30°"), ("oat45", "45°"), ("oat60", "60°")]
HEMI = [("hemisphere-0", "[0°]"), ("hemisphere-45", "[45°]"), ("hemisphere-0-90", "[0°/90°]")]
TETRA = [("tetrahedron-0", "[0°]"), ("tetrahedron-45", "[45°]"), ("tetrahedron-90", "[90°]")]

# The deformation modes of docs/forming.md, "Deformation modes" (the codes
# of the VTU field `deformation_mode`; the names of full_validation.py).
MODE_NAMES = ["near reference", "mixed-mode 1", "mixed-mode 2", "I11 ≥ 1, I8 > 1 (transverse tension)",
              "I11 ≥ 1, I8 ≤ 1 (the rest)"]
MODE_COLOURS = ["#d9d9d9", "#4c72b0", "#dd8452", "#c44e52", "#8172b2"]

ZONE_COLOURS = {"A": "tab:blue", "B": "tab:orange", "C": "tab:green"}
PLY_STYLE = {"ply-0": ("tab:blue", "-", "Blues"), "ply-90": ("tab:red", "--", "Reds")}
QUANTITIES = [("shear_angle_deg", "γ", "shear angle γ [deg]"),
              ("E22", "E22", "E22 = I8 − 1 [-]"),
              ("E_perp", "E⊥", "E⊥ = I11 − 1 [-]")]

plt.rcParams.update({"font.size": 9, "axes.titlesize": 9.5, "axes.labelsize": 9,
                     "legend.fontsize": 7.5, "figure.dpi": DPI, "savefig.dpi": DPI})

written = []


class Missing(Exception):
    pass


def need(path):
    if not os.path.exists(path):
        raise Missing(f"paper_figures.py: missing {path} (the run folder lacks it; "
                      f"make the run with `full_validation.py --keep DIR` or "
                      f"`ncform run cases/<case>.toml --out DIR/<case>`)")
    return path


def read_csv(path):
    """Header names and rows of an ncform CSV (`# ` preamble; an empty field
    is NaN)."""
    with open(need(path)) as f:
        lines = [line for line in f if not line.startswith("#")]
    header = lines[0].strip().split(",")
    data = np.genfromtxt(lines[1:], delimiter=",", dtype=float)
    return header, np.atleast_2d(data)


def save(fig, out, name):
    """Writes the figure as a PNG of 256 colours (the maps' colour scales have
    256 levels; a third of the size of the full-colour PNG)."""
    path = os.path.join(out, name)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    buf.seek(0)
    im = Image.open(buf).convert("RGB")
    # an adaptive palette, plus the exact colours of the lines and patches
    # (few pixels, which an adaptive palette alone would merge into others)
    exact = [matplotlib.colors.to_rgb(c) for c in
             list(plt.get_cmap("tab10").colors) + MODE_COLOURS + ["magenta", "black", "white", "0.6"]]
    exact = [int(round(255 * x)) for c in exact for x in c]
    adaptive = im.quantize(colors=256 - len(exact) // 3, method=Image.Quantize.MEDIANCUT,
                           dither=Image.Dither.NONE).getpalette()[:3 * (256 - len(exact) // 3)]
    pal = np.array(adaptive + exact, dtype=float).reshape(-1, 3)
    rgb = np.asarray(im)
    colours, inverse = np.unique(rgb.reshape(-1, 3), axis=0, return_inverse=True)
    nearest = np.empty(len(colours), dtype=np.uint8)
    for i in range(0, len(colours), 4096):  # each colour to its nearest entry, exactly
        d = ((colours[i:i + 4096, None, :].astype(float) - pal[None, :, :]) ** 2).sum(axis=2)
        nearest[i:i + 4096] = d.argmin(axis=1)
    out = Image.fromarray(nearest[inverse.ravel()].reshape(rgb.shape[:2]), mode="P")
    out.putpalette([int(x) for x in pal.ravel()])
    out.save(path, optimize=True)
    written.append(path)
    print(f"# wrote {path} ({os.path.getsize(path) / 1024:.0f} kB)", flush=True)


# --- run folders -------------------------------------------------------------

class Run:
    """A forming run folder: summary, output states, ply VTUs."""

    def __init__(self, runs, case):
        self.case = case
        self.dir = os.path.join(runs, case)
        self.summary = json.load(open(need(os.path.join(self.dir, "summary.json"))))
        f = self.summary["forming"]
        self.strokes = [st["stroke"] for st in f["states"]]
        self.zones = [{"name": z[0], "ply": z[1], "centre": z[2], "size": z[3]} for z in f["zones"]]
        self.plies = [p["name"] for p in self.summary["plies"]]
        self.case_file = os.path.join(CASES, f"{case}.toml")
        self._vtu = {}

    def vtu(self, ply, state):
        """The ply's VTU at output state `state` (1-based): reference and
        current positions, triangles, cell fields."""
        key = (ply, state)
        if key not in self._vtu:
            m = meshio.read(need(os.path.join(self.dir, "vtu", f"{ply}_{state:04d}.vtu")))
            tri = m.cells_dict["triangle"]
            ref = m.points - m.point_data["displacement"]
            e1 = ref[tri[:, 1], :2] - ref[tri[:, 0], :2]
            e2 = ref[tri[:, 2], :2] - ref[tri[:, 0], :2]
            a = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
            self._vtu[key] = {"cur": m.points, "ref": ref, "tri": tri, "area": a,
                              "refc": ref[tri].mean(axis=1),
                              "cells": {k: v["triangle"] for k, v in m.cell_data_dict.items()
                                        if "triangle" in v}}
        return self._vtu[key]

    def final(self):
        return len(self.strokes)

    def state_at(self, depth):
        """The output state nearest to `depth` [mm] (1-based)."""
        return int(np.argmin([abs(s - depth) for s in self.strokes])) + 1


def load_runs(runs, names):
    got = {}
    for case in names:
        if os.path.isdir(os.path.join(runs, case)):
            got[case] = Run(runs, case)
        else:
            print(f"# no run folder {os.path.join(runs, case)}: its panels are left out", flush=True)
    return got


# --- the die opening ---------------------------------------------------------

def circle(r, n=361):
    t = np.linspace(0, 2 * np.pi, n)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def rounded_polygon(sides, inner, radius, first_corner_deg, n=60):
    """The outline of a regular polygon whose corners lie `inner` from the
    axis, grown by `radius` (straight sides, circular corners)."""
    pts = []
    half = 180.0 / sides
    for k in range(sides):
        t = np.radians(first_corner_deg + 360.0 * k / sides)
        c = inner * np.array([np.cos(t), np.sin(t)])
        a = np.radians(np.linspace(np.degrees(t) - half, np.degrees(t) + half, n))
        pts.append(c + radius * np.column_stack([np.cos(a), np.sin(a)]))
    pts = np.vstack(pts)
    return np.vstack([pts, pts[:1]])


def die_outlines(run):
    return _die_outlines(run.case_file)


@functools.lru_cache(maxsize=None)
def _die_outlines(case_file):
    """[(label, xy)]: the die's opening and the outer edge of its fillet
    in the die plane, from the case file's `die` tool (docs/cases.md,
    `[[tool]]`; the pyramid's opening as docs/forming.md, "Geometry and
    defaults", describes it)."""
    case = tomllib.load(open(need(case_file), "rb"))
    tools = {t["name"]: t for t in case.get("tool", [])}
    die = tools.get("die")
    if die is None:
        return []
    f = die.get("fillet_radius", 0.0)
    if die["shape"] == "plate-with-hole":
        r = die["opening_radius"]
        return [(f"die opening R {r:g} mm", circle(r)),
                (f"fillet's outer edge R {r + f:g} mm", circle(r + f))]
    if die["shape"] == "plate-with-polygon-hole":
        p = tools[die["punch"]]
        n = p.get("sides", 3)
        alpha = np.radians(p.get("face_angle_deg", 70.5288))
        r = p["rounding_radius"]
        zd = die.get("section_at", die["origin"])[2]
        # the sharp core's apex at full stroke: one rounding radius above the
        # rounded apex's lowest point (`origin`), moved by the stroke
        apex = p["origin"][2] + r - p["displacement"]
        h = zd - apex
        side = h / np.tan(alpha) + r / np.sin(alpha) + die["clearance"]
        beta = np.arctan(np.tan(alpha) * np.cos(np.pi / n))
        extreme = h / np.tan(alpha) / np.cos(np.pi / n) + r / np.sin(beta) + die["clearance"]
        d = (extreme - side) / (1 - np.cos(np.pi / n))
        rc = extreme - d
        e = np.asarray(p.get("edge_direction", [1, 0, 0]), float)
        # the base edge along e on the side of -(axis x e): its corner opposite
        edge_normal = -np.cross([0, 0, 1], e)[:2]
        first = np.degrees(np.arctan2(-edge_normal[1], -edge_normal[0]))
        print(f"# {os.path.basename(case_file)}: die opening: sides {side:.2f} mm from the axis, corners "
              f"R {rc:.2f} mm, corner extremes {extreme:.2f} mm; fillet {f:g} mm", flush=True)
        return [(f"die opening (sides {side:.1f} mm from the axis, corners R {rc:.1f} mm)",
                 rounded_polygon(n, d, rc, first)),
                (f"fillet's outer edge (+{f:g} mm)", rounded_polygon(n, d, rc + f, first))]
    return []


def draw_die(ax, outlines, legend=True):
    for k, (label, xy) in enumerate(outlines):
        ax.plot(xy[:, 0], xy[:, 1], color="black", lw=0.9 if k == 0 else 0.7,
                ls="-" if k == 0 else ":", label=label if legend else None, zorder=5)


# --- zone windows --------------------------------------------------------------

def window_outline(centre, size, n=30):
    cx, cy = centre
    w, h = size
    xs = np.linspace(cx - w / 2, cx + w / 2, n)
    ys = np.linspace(cy - h / 2, cy + h / 2, n)
    return np.vstack([np.column_stack([xs, np.full(n, cy - h / 2)]),
                      np.column_stack([np.full(n, cx + w / 2), ys]),
                      np.column_stack([xs[::-1], np.full(n, cy + h / 2)]),
                      np.column_stack([np.full(n, cx - w / 2), ys[::-1]])])


def to_current(v, pts):
    """Reference points on the blank -> current x, y (linear interpolation
    of the current positions over the reference mesh)."""
    t = mtri.Triangulation(v["ref"][:, 0], v["ref"][:, 1], v["tri"])
    out = []
    for c in (0, 1):
        out.append(mtri.LinearTriInterpolator(t, v["cur"][:, c])(pts[:, 0], pts[:, 1]))
    return np.column_stack([np.ma.filled(out[0], np.nan), np.ma.filled(out[1], np.nan)])


def in_window(refc, centre, size):
    return ((np.abs(refc[:, 0] - centre[0]) <= size[0] / 2)
            & (np.abs(refc[:, 1] - centre[1]) <= size[1] / 2))


def draw_windows(ax, v, windows, colour=None, ls="-"):
    for w in windows:
        xy = to_current(v, window_outline(w["centre"], w["size"]))
        c = colour or ZONE_COLOURS.get(w["name"], "magenta")
        # a white halo keeps the window visible on any colour of the map
        ax.plot(xy[:, 0], xy[:, 1], color=c, lw=1.3, ls=ls, zorder=6,
                path_effects=[patheffects.withStroke(linewidth=2.6, foreground="white")])
        i = np.nanargmax(xy[:, 1])
        ax.text(xy[i, 0], xy[i, 1] + 3, w["name"], color=c, fontsize=8, fontweight="bold",
                ha="center", va="bottom", zorder=7,
                bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.7))


def windows_for(run, ply, extra):
    """The case's windows on this ply; the stack's 90° ply takes the 0° ply's
    windows (its own case has none there; drawn dashed); plus the --windows
    ones."""
    own = [z for z in run.zones if z["ply"] == ply]
    borrowed = [] if own else [z for z in run.zones]
    more = [w for w in extra if not w.get("cases") or run.case in w["cases"]]
    return own, borrowed, more


# --- colour scales --------------------------------------------------------------

def signed_norm(values, symmetric=False, pct=0.5):
    """A norm centred on 0 over the 0.5-99.5 % percentiles of `values`;
    the label text giving the range."""
    v = np.concatenate([np.ravel(x) for x in values])
    v = v[np.isfinite(v)]
    lo, hi = np.percentile(v, [pct, 100 - pct])
    if symmetric:
        m = max(abs(lo), abs(hi))
        lo, hi = -m, m
    if lo < 0 < hi:
        norm = TwoSlopeNorm(0.0, lo, hi) if not symmetric else Normalize(lo, hi)
        cmap = "RdBu_r"
    else:
        norm = Normalize(lo, hi)
        cmap = "viridis"
    return norm, cmap, lo, hi


def fmt(x):
    return f"{x:+.3g}" if abs(x) < 10 else f"{x:+.1f}"


def range_label(label, lo, hi, pct=0.5):
    return (f"{label}\ncolour range {fmt(lo)} … {fmt(hi)}\n(the {pct:g}–{100 - pct:g} % "
            f"percentiles of all panels; saturated beyond)")


def colourbar(fig, mappable, axes, label, **kw):
    cb = fig.colorbar(mappable, ax=axes, shrink=kw.pop("shrink", 0.9), pad=kw.pop("pad", 0.02), **kw)
    cb.set_label(label, fontsize=8)
    cb.ax.tick_params(labelsize=7.5)
    norm = mappable.norm
    if isinstance(norm, TwoSlopeNorm):
        # evenly spaced ticks on each side of 0 (the two halves have their own scales)
        ticks = [norm.vmin, norm.vmin / 2, 0.0, norm.vmax / 2, norm.vmax]
        cb.set_ticks(ticks)
        cb.set_ticklabels([f"{t:.3g}" for t in ticks])
    return cb


def map_panel(ax, v, values, norm, cmap, below=True):
    """Cell values on the current x-y projection; the lowest material drawn
    last (a camera below sees it in front)."""
    tri = v["tri"]
    zc = v["cur"][tri, 2].mean(axis=1)
    order = np.argsort(-zc) if below else np.argsort(zc)
    t = mtri.Triangulation(v["cur"][:, 0], v["cur"][:, 1], tri[order])
    pc = ax.tripcolor(t, facecolors=np.asarray(values)[order], norm=norm, cmap=cmap,
                      edgecolors="none", rasterized=True)
    ax.set_aspect("equal")
    if below:
        ax.invert_xaxis()
    return pc


def map_axes(ax, lim):
    ax.set_xlim(lim, -lim)
    ax.set_ylim(-lim, lim)
    ax.tick_params(labelsize=7)


# --- Fig. 4: OAT contours ------------------------------------------------------

def last_oat_vtu(d):
    folder = os.path.join(d, "vtu")
    names = sorted(n for n in os.listdir(need(folder)) if n.startswith("oat_d") and n.endswith(".vtu"))
    if not names:
        raise Missing(f"paper_figures.py: missing {folder}/oat_dXXX.XXX.vtu (no OAT state)")
    return os.path.join(folder, names[-1]), float(names[-1][5:-4])


def fig4(runs, out):
    present = [(c, a) for c, a in OAT_CASES if os.path.isdir(os.path.join(runs, c))]
    if not present:
        print("# Fig. 4/6: no OAT run folders, skipped")
        return
    meshes = []
    for c, a in present:
        path, d = last_oat_vtu(os.path.join(runs, c))
        m = meshio.read(path)
        meshes.append((c, a, d, m))
    n = len(meshes)
    fig, axes = plt.subplots(1, 3 * n, figsize=(1.45 * 3 * n + 0.6, 7.3), squeeze=False,
                             constrained_layout=True)
    for q, (field, short, label) in enumerate(QUANTITIES):
        vals = [m.cell_data_dict[field]["triangle"] for *_, m in meshes]
        if field == "E22":
            # E22 is near 1 in the 30° test's band and some 0.05 elsewhere: a
            # linear scale shared by the three would wash the 45° and 60° tests
            # out, so the scale is linear within ±0.02 and logarithmic beyond
            _, _, lo, hi = signed_norm(vals, symmetric=True)
            norm, cmap = SymLogNorm(linthresh=0.02, vmin=lo, vmax=hi, base=10), "RdBu_r"
            lab = range_label(label + " (linear within ±0.02, logarithmic beyond)", lo, hi)
        else:
            norm, cmap, lo, hi = signed_norm(vals, symmetric=(field == "shear_angle_deg"))
            lab = range_label(label, lo, hi)
        for k, (c, a, d, m) in enumerate(meshes):
            ax = axes[0, q * n + k]
            t = mtri.Triangulation(m.points[:, 0], m.points[:, 1], m.cells_dict["triangle"])
            pc = ax.tripcolor(t, facecolors=vals[k], norm=norm, cmap=cmap, rasterized=True)
            ax.set_aspect("equal")
            ax.set_title(f"{a}-OAT\n{short}, {d:.0f} mm", fontsize=8.5)
            ax.set_xlabel("x [mm]", fontsize=7.5)
            if q == 0 and k == 0:
                ax.set_ylabel("y [mm]")
            else:
                ax.set_yticklabels([])
            ax.tick_params(labelsize=7)
        colourbar(fig, pc, axes[0, q * n:(q + 1) * n], lab, location="bottom", shrink=0.95,
                  pad=0.01, aspect=18)
    fig.suptitle("Off-axis tension tests at the final clamp displacement: the deformed specimens "
                 "(paper Fig. 4, simulation side);\none colour range per quantity over the three "
                 "tests, diverging, white = 0", fontsize=9.5)
    save(fig, out, "oat-contours.png")


# --- Fig. 6: OAT curves ----------------------------------------------------------

def fig6(runs, out):
    present = [(c, a) for c, a in OAT_CASES + [("oat45-explicit", "45° (explicit solver)")]
               if os.path.isdir(os.path.join(runs, c))]
    if not present:
        return
    colours = {"oat30": "tab:blue", "oat45": "tab:orange", "oat60": "tab:green",
               "oat45-explicit": "black"}
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.2), constrained_layout=True)
    for c, a in present:
        ls = ":" if c.endswith("explicit") else "-"
        lw = 1.0 if c.endswith("explicit") else 1.6
        _, fd = read_csv(os.path.join(runs, c, "force_displacement.csv"))
        h, md = read_csv(os.path.join(runs, c, "mdz_strains.csv"))
        x0 = np.concatenate([[0.0], fd[:, 0]])
        name = f"{a.split(' ')[0]}-OAT{a[3:]}"
        axes[0, 0].plot(x0, np.concatenate([[0.0], fd[:, 1]]), color=colours[c], ls=ls, lw=lw,
                        label=name)
        cols = {n.split(" [")[0]: k for k, n in enumerate(h)}
        for ax, key, lab in ((axes[0, 1], "shear_angle", "MDZ mean shear angle γ [deg]"),
                             (axes[1, 0], "E22", "MDZ mean E22 = I8 − 1 [-]"),
                             (axes[1, 1], "E_perp", "MDZ mean E⊥ = I11 − 1 [-]")):
            if key not in cols:
                raise Missing(f"paper_figures.py: {os.path.join(runs, c, 'mdz_strains.csv')} has no "
                              f"column {key}")
            ax.plot(np.concatenate([[0.0], md[:, 0]]), np.concatenate([[0.0], md[:, cols[key]]]),
                    color=colours[c], ls=ls, lw=lw, label=name)
            ax.set_ylabel(lab)
    axes[0, 0].set_ylabel("clamp force [N]")
    for ax in axes.flat:
        ax.set_xlabel("clamp displacement [mm]")
        ax.grid(alpha=0.3)
        ax.axhline(0, color="grey", lw=0.6)
        ax.set_xlim(left=0)
    axes[0, 0].legend(loc="upper left")
    axes[0, 0].set_title("force–displacement")
    axes[0, 1].set_title("MDZ shear angle")
    axes[1, 0].set_title("MDZ transverse strain E22")
    axes[1, 1].set_title("MDZ perpendicular strain E⊥")
    fig.suptitle("Off-axis tension tests: clamp force and main-deformation-zone (MDZ) means against the "
                 "clamp displacement\n(paper Fig. 6, simulation side; no standard-deviation bands: "
                 "mdz_strains.csv holds the means only)", fontsize=9.5)
    save(fig, out, "oat-curves.png")


# --- Fig. 8: outer contours ---------------------------------------------------------

def contours(run):
    """{ply number: (reference xy, [xy at each output state])}."""
    return findings.contours(run.dir)


def closed(xy):
    return np.vstack([xy, xy[:1]])


def contour_panel(ax, run, title):
    plies = contours(run)
    draw_die(ax, die_outlines(run))
    n = len(run.strokes)
    for p, (ref, states) in plies.items():
        name = run.plies[p - 1]
        ax.plot(*closed(ref).T, color="0.6", lw=0.8, ls="-" if p == 1 else "--",
                label="reference blank" if p == 1 else None)
        if len(plies) == 1:
            cols = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, n))
            ls = "-"
        else:
            colour, ls, cmap = PLY_STYLE.get(name, ("k", "-.", "Greys"))
            cols = plt.get_cmap(cmap)(np.linspace(0.45, 1.0, n))
        for k, xy in enumerate(states):
            lab = f"{run.strokes[k]:.0f} mm" if len(plies) == 1 else f"{name}, {run.strokes[k]:.0f} mm"
            ax.plot(*closed(xy).T, color=cols[k], lw=1.1, ls=ls, label=lab)
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(alpha=0.25)
    if len(plies) > 1:
        # one entry per ply (its deepest state); lighter: shallower
        from matplotlib.lines import Line2D
        hs = []
        for p in plies:
            name = run.plies[p - 1]
            colour, ls, cmap = PLY_STYLE.get(name, ("k", "-.", "Greys"))
            hs.append(Line2D([], [], color=plt.get_cmap(cmap)(1.0), ls=ls, lw=1.3,
                             label=f"{name}: {run.strokes[0]:.0f} … {run.strokes[-1]:.0f} mm"))
        ax.legend(handles=hs, loc="center", fontsize=7, title="lighter: shallower",
                  title_fontsize=7, framealpha=0.9)


def fig8(runs, out):
    for group, fname, depth_word in ((HEMI, "hemisphere-contours.png", "hemisphere"),
                                     (TETRA, "tetrahedron-contours.png", "tetrahedron")):
        got = load_runs(runs, [c for c, _ in group])
        if not got:
            continue
        fig, axes = plt.subplots(1, len(got), figsize=(5.0 * len(got), 5.6), squeeze=False,
                                 constrained_layout=True)
        for ax, (case, run) in zip(axes[0], got.items()):
            lay = dict(group)[case]
            contour_panel(ax, run, f"{depth_word} {lay}")
        # the entries the panels share: die, reference blank, the depths' colours
        single = [ax for ax, run in zip(axes[0], got.values()) if len(run.plies) == 1]
        handles, labels = (single[0] if single else axes[0][0]).get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8,
                   frameon=False)
        fig.suptitle(f"Outer contours of the {depth_word} plies at every output depth, projected on the "
                     "blank plane, seen from above (paper Fig. 8"
                     f"{'a' if depth_word == 'hemisphere' else 'b'}); black: the die's opening, "
                     "dotted: its fillet's outer edge", fontsize=9.5)
        save(fig, out, fname)


# --- Figs. 9-11: strain maps ----------------------------------------------------------

def ply_label(run, ply, lay):
    if len(run.plies) == 1:
        return lay
    angle = ply.split("-")[-1]
    return f"{lay}, {angle}° ply"


def map_entries(got, group):
    entries = []
    for case, lay in group:
        if case in got:
            run = got[case]
            for ply in run.plies:
                entries.append((run, ply, ply_label(run, ply, lay)))
    return entries


def draw_overlays(ax, run, ply, v, extra, outlines):
    draw_die(ax, outlines, legend=False)
    own, borrowed, more = windows_for(run, ply, extra)
    draw_windows(ax, v, own)
    draw_windows(ax, v, borrowed, ls="--")
    draw_windows(ax, v, more, colour="magenta", ls="-.")


def strain_maps(got, group, bench, lim, out, extra):
    entries = map_entries(got, group)
    if not entries:
        return
    # full depth: runs x quantities
    finals = [(run, ply, lab, run.vtu(ply, run.final())) for run, ply, lab in entries]
    fig, axes = plt.subplots(len(finals), 3, figsize=(11.5, 3.55 * len(finals)), squeeze=False,
                             constrained_layout=True)
    for col, (field, short, label) in enumerate(QUANTITIES):
        vals = [v["cells"][field] for *_, v in finals]
        norm, cmap, lo, hi = signed_norm(vals, symmetric=(field == "shear_angle_deg"))
        for row, (run, ply, lab, v) in enumerate(finals):
            ax = axes[row, col]
            pc = map_panel(ax, v, vals[row], norm, cmap)
            draw_overlays(ax, run, ply, v, extra, die_outlines(run))
            map_axes(ax, lim)
            ax.set_title(f"{bench} {lab}: {short} at {run.strokes[-1]:.0f} mm")
            ax.set_xlabel("x [mm] (seen from below: x grows to the left)", fontsize=7.5)
            ax.set_ylabel("y [mm]", fontsize=7.5)
        colourbar(fig, pc, axes[:, col], range_label(label, lo, hi), location="bottom", shrink=0.9,
                  pad=0.01, aspect=30)
    fig.suptitle(f"{bench.capitalize()} at full depth, strains of the formed plies seen from below "
                 f"(x–y projection of the current positions, mirrored) "
                 f"(paper Fig. {'9' if bench == 'hemisphere' else '11'}, simulation side).\n"
                 "Black: die opening; dotted: fillet's outer edge; A, B, C: the case's zone windows "
                 "moved with the material (dashed on the 90° ply: the 0° ply's windows)"
                 + ("; magenta: --windows" if extra else ""), fontsize=9.5)
    save(fig, out, f"{bench}-strains-full-depth.png")
    # every depth: one figure per quantity, runs x depths
    for field, short, label in QUANTITIES:
        n = max(len(run.strokes) for run, *_ in entries)
        vs = [[run.vtu(ply, s) for s in range(1, len(run.strokes) + 1)] for run, ply, _ in entries]
        vals = [v["cells"][field] for row in vs for v in row]
        norm, cmap, lo, hi = signed_norm(vals, symmetric=(field == "shear_angle_deg"))
        fig, axes = plt.subplots(len(entries), n, figsize=(2.45 * n + 0.4, 2.55 * len(entries) + 0.9),
                                 squeeze=False, constrained_layout=True)
        for row, ((run, ply, lab), vrow) in enumerate(zip(entries, vs)):
            outlines = die_outlines(run)
            for s, v in enumerate(vrow):
                ax = axes[row, s]
                pc = map_panel(ax, v, v["cells"][field], norm, cmap)
                draw_overlays(ax, run, ply, v, extra, outlines)
                map_axes(ax, lim)
                ax.set_title(f"{lab}, {run.strokes[s]:.0f} mm", fontsize=8.5)
                ax.tick_params(labelsize=6)
                if s == 0:
                    ax.set_ylabel("y [mm]", fontsize=7)
                if row == len(entries) - 1:
                    ax.set_xlabel("x [mm] (from below)", fontsize=7)
        colourbar(fig, pc, axes, range_label(label, lo, hi), location="bottom", shrink=0.7,
                  pad=0.01, aspect=40)
        fig.suptitle(f"{bench.capitalize()}: {label} at every output depth, seen from below "
                     "(mirrored: x grows to the left); die opening, fillet edge and zone windows "
                     "as in the full-depth figure", fontsize=9.5)
        save(fig, out, f"{bench}-{short.replace('γ', 'shear').replace('⊥', '_perp')}-depths.png")


# --- Fig. 10: zone shear against the stroke ---------------------------------------------

def zone_stats(v, field, w):
    inside = in_window(v["refc"], w["centre"], w["size"])
    a = v["area"][inside]
    x = v["cells"][field][inside]
    m = float((a * x).sum() / a.sum())
    return m, float(np.sqrt((a * (x - m) ** 2).sum() / a.sum())), int(inside.sum())


def fig10(got_h, got_t, out):
    panels = []
    for group, got in ((HEMI, got_h), (TETRA, got_t)):
        for case, lay in group:
            if case not in got:
                continue
            run = got[case]
            bench = case.split("-")[0]
            h, data = read_csv(os.path.join(run.dir, "forming.csv"))
            for ply in run.plies:
                own = [z for z in run.zones if z["ply"] == ply]
                title = f"{bench} {ply_label(run, ply, lay)}"
                if own:
                    curves = []
                    for z in own:
                        cm = h.index(f"zone {z['name']} shear angle mean [deg]")
                        cs = h.index(f"zone {z['name']} shear angle std [deg]")
                        curves.append((z["name"], data[:, 0], data[:, cm], data[:, cs], False))
                    # the VTU means at the output states against the CSV's: the same
                    # windows read the same way
                    for z in own:
                        m, _, _ = zone_stats(run.vtu(ply, run.final()), "shear_angle_deg", z)
                        ref = run.summary["forming"]["states"][-1]["zones"][run.zones.index(z)]
                        if abs(m - ref["shear_angle_mean"]) > 1e-6:
                            print(f"# note: {case} zone {z['name']}: VTU mean {m:.4f} vs "
                                  f"summary {ref['shear_angle_mean']:.4f} deg")
                else:
                    # the stack's 90° ply has no zones in its case: the 0° ply's windows
                    # read from its VTUs at the output states
                    curves = []
                    for z in run.zones:
                        st = [zone_stats(run.vtu(ply, s), "shear_angle_deg", z)
                              for s in range(1, len(run.strokes) + 1)]
                        curves.append((z["name"], np.array([0.0] + run.strokes),
                                       np.array([0.0] + [x[0] for x in st]),
                                       np.array([0.0] + [x[1] for x in st]), True))
                    title += "\n(the 0° ply's windows, from the VTUs at the output depths)"
                panels.append((bench, title, curves))
    if not panels:
        return
    hemi = [p for p in panels if p[0] == "hemisphere"]
    tet = [p for p in panels if p[0] == "tetrahedron"]
    if "hemisphere-0" in got_h and "hemisphere-0-90" in got_h:
        # the stack's 0° ply against the single [0°] ply, zone by zone (docs/validation.md)
        (h1, d1), (h2, d2) = (read_csv(os.path.join(got_h[c].dir, "forming.csv"))
                              for c in ("hemisphere-0", "hemisphere-0-90"))
        curves = []
        for z in got_h["hemisphere-0-90"].zones:
            col = f"zone {z['name']} shear angle mean [deg]"
            if col in h1 and col in h2:
                b = np.interp(d1[:, 0], d2[:, 0], d2[:, h2.index(col)])
                curves.append((z["name"], d1[:, 0], b - d1[:, h1.index(col)], None, False))
        diff = ("difference", "hemisphere: 0° ply of [0°/90°] − single [0°] ply\n(zone means; "
                "no bands)", curves)
        (tet if len(tet) < len(hemi) else hemi).append(diff)
    ncol = max(len(hemi), len(tet))
    nrow = (1 if hemi else 0) + (1 if tet else 0)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 3.6 * nrow), squeeze=False,
                             constrained_layout=True)
    for r, row in enumerate([x for x in (hemi, tet) if x]):
        lo = min(np.nanmin(m - s) for p in row if p[0] != "difference" for _, _, m, s, _ in p[2])
        hi = max(np.nanmax(m + s) for p in row if p[0] != "difference" for _, _, m, s, _ in p[2])
        for c in range(ncol):
            ax = axes[r, c]
            if c >= len(row):
                ax.axis("off")
                continue
            bench, title, curves = row[c]
            for name, x, m, s, markers in curves:
                col = ZONE_COLOURS.get(name, "k")
                if s is not None:
                    ax.fill_between(x, m - s, m + s, color=col, alpha=0.18, lw=0)
                ax.plot(x, m, color=col, lw=1.5, marker="o" if markers else None, ms=3,
                        label=f"zone {name}")
            ax.set_title(title, fontsize=8.5)
            if bench != "difference":
                ax.set_ylim(lo - 2, hi + 2)
                ax.set_ylabel("zone mean shear angle γ [deg]")
            else:
                ax.set_ylabel("difference of the zone means of γ [deg]")
            ax.axhline(0, color="grey", lw=0.6)
            ax.grid(alpha=0.3)
            ax.set_xlabel("punch displacement [mm]")
            ax.legend(loc="upper left", fontsize=7)
    fig.suptitle("Mean shear angle in the zones against the punch displacement (paper Fig. 10); "
                 "bands: ± one standard deviation over the zone (area-weighted)", fontsize=9.5)
    save(fig, out, "zone-shear.png")


# --- deformation modes -------------------------------------------------------------------

def fig_modes(got_h, got_t, out, extra):
    entries = map_entries(got_h, HEMI) + map_entries(got_t, TETRA)
    if not entries:
        return
    cmap = ListedColormap(MODE_COLOURS)
    norm = BoundaryNorm(np.arange(-0.5, len(MODE_COLOURS) + 0.5), cmap.N)
    ncol = 4
    nrow = int(np.ceil(len(entries) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.4 * ncol, 3.5 * nrow + 0.6), squeeze=False,
                             constrained_layout=True)
    for k, (run, ply, lab) in enumerate(entries):
        ax = axes.flat[k]
        v = run.vtu(ply, run.final())
        if "deformation_mode" not in v["cells"]:
            raise Missing(f"paper_figures.py: {run.dir}/vtu/{ply}_{run.final():04d}.vtu has no "
                          "cell field deformation_mode")
        map_panel(ax, v, v["cells"]["deformation_mode"], norm, cmap)
        draw_overlays(ax, run, ply, v, extra, die_outlines(run))
        bench = run.case.split("-")[0]
        map_axes(ax, 160 if bench == "hemisphere" else 210)
        modes = [m for m in run.summary["forming"]["deformation_modes"]
                 if m["ply"] == ply and abs(m["stroke"] - run.strokes[-1]) < 1e-6]
        share = ""
        if modes:
            a = np.array(modes[0]["areas"])
            share = (f"\nmixed-mode 1 {100 * a[1] / a.sum():.0f} %, "
                     f"mixed-mode 2 {100 * a[2] / a.sum():.0f} % of the ply")
        ax.set_title(f"{bench} {lab}, {run.strokes[-1]:.0f} mm{share}", fontsize=8.5)
        ax.set_xlabel("x [mm] (from below)", fontsize=7)
        ax.set_ylabel("y [mm]", fontsize=7)
    for ax in axes.flat[len(entries):]:
        ax.axis("off")
    handles = [Patch(facecolor=c, edgecolor="0.3", label=f"{k}: {n}")
               for k, (c, n) in enumerate(zip(MODE_COLOURS, MODE_NAMES))]
    title = ("deformation mode\n(signs of I11 − 1 and I8 − 1\nbeyond ±0.1 %; docs/forming.md,\n"
             "\"Deformation modes\")")
    if len(entries) < axes.size:
        axes.flat[len(entries)].legend(handles=handles, loc="center", fontsize=8.5, title=title,
                                       title_fontsize=8.5, frameon=True)
    else:
        fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8,
                   title=title.replace("\n", " "), title_fontsize=8)
    fig.suptitle("Deformation modes of every ply at full depth, seen from below (mirrored) "
                 "(paper Section 5.3, Fig. 2d); shares: reference areas from summary.json",
                 fontsize=9.5)
    save(fig, out, "deformation-modes.png")


# --- the stack's redistribution ------------------------------------------------------------

def fig_stack(got_h, out, extra):
    if "hemisphere-0" not in got_h or "hemisphere-0-90" not in got_h:
        print("# stack redistribution: needs hemisphere-0 and hemisphere-0-90, skipped")
        return []
    single, stack = got_h["hemisphere-0"], got_h["hemisphere-0-90"]
    sply, kply = single.plies[0], "ply-0" if "ply-0" in stack.plies else stack.plies[0]
    depths = [d for d in (30.0, 45.0, 60.0, 75.0) if min(abs(np.array(stack.strokes) - d)) < 0.5]
    vs = single.vtu(sply, 1)
    vk = stack.vtu(kply, 1)
    same = (vs["ref"].shape == vk["ref"].shape and vs["tri"].shape == vk["tri"].shape
            and np.array_equal(vs["tri"], vk["tri"])
            and np.allclose(vs["ref"][:, :2], vk["ref"][:, :2], atol=1e-6))
    if same:
        match = np.arange(len(vk["tri"]))
        how = "the two meshes coincide element by element (same reference nodes and triangles)"
    else:
        from scipy.spatial import cKDTree
        d, match = cKDTree(vs["refc"][:, :2]).query(vk["refc"][:, :2])
        how = (f"the meshes differ: each element of the stack's ply is matched to the single ply's "
               f"element of nearest reference centroid (largest distance {d.max():.3f} mm)")
    print(f"# stack redistribution: {how}", flush=True)
    diffs, rows = [], []
    for d in depths:
        a = stack.vtu(kply, stack.state_at(d))
        b = single.vtu(sply, single.state_at(d))
        diff = a["cells"]["shear_angle_deg"] - b["cells"]["shear_angle_deg"][match]
        diffs.append((d, a, diff))
        zs = [z for z in stack.zones if z["ply"] == kply]
        for z in zs:
            inside = in_window(a["refc"], z["centre"], z["size"])
            w = a["area"][inside]
            rows.append((d, z["name"], float((w * diff[inside]).sum() / w.sum()), int(inside.sum())))
        for w_ in extra:
            if w_.get("cases") and "hemisphere-0-90" not in w_["cases"]:
                continue
            inside = in_window(a["refc"], w_["centre"], w_["size"])
            if inside.any():
                w = a["area"][inside]
                rows.append((d, w_["name"], float((w * diff[inside]).sum() / w.sum()), int(inside.sum())))
    # the shear bands at the die's edge differ by tens of degrees between the two
    # runs; a range over the 5-95 % percentiles keeps the few degrees of the
    # zones visible
    norm, cmap, lo, hi = signed_norm([x[2] for x in diffs], symmetric=True, pct=5.0)
    fig, axes = plt.subplots(1, len(diffs), figsize=(3.5 * len(diffs) + 0.5, 4.6), squeeze=False,
                             constrained_layout=True)
    outlines = die_outlines(stack)
    for ax, (d, a, diff) in zip(axes[0], diffs):
        pc = map_panel(ax, a, diff, norm, cmap)
        draw_overlays(ax, stack, kply, a, extra, outlines)
        map_axes(ax, 160)
        means = ", ".join(f"{n} {m:+.1f}°" for dd, n, m, _ in rows if dd == d)
        ax.set_title(f"{d:.0f} mm\nzone means: {means}", fontsize=8.5)
        ax.set_xlabel("x [mm] (from below)", fontsize=7.5)
        ax.set_ylabel("y [mm]", fontsize=7.5)
    label = "γ(0° ply of [0°/90°]) − γ(single [0°] ply) [deg]"
    colourbar(fig, pc, axes[0, :], range_label(label, lo, hi, pct=5.0),
              location="bottom", shrink=0.6, pad=0.02, aspect=40)
    fig.suptitle("Hemisphere: shear redistribution by the 90° ply (paper Fig. 10a, Section 5.2), element "
                 "by element on the stack's 0° ply's current positions, seen from below;\nred: the stack "
                 "shears more; zone means area-weighted over the windows (reference centroids)",
                 fontsize=9.5)
    save(fig, out, "hemisphere-stack-minus-single.png")
    print("# stack − single, area-weighted mean of γ difference in each window [deg]:")
    for d, n, m, k in rows:
        print(f"#   {d:.0f} mm window {n}: {m:+.2f}° ({k} elements)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", required=True, help="folder of run folders DIR/<case>/")
    ap.add_argument("--out", required=True, help="where the PNGs go (docs/figures)")
    ap.add_argument("--windows", help="JSON list of extra windows {name, centre, size} [mm]")
    args = ap.parse_args()
    if not os.path.isdir(args.runs):
        raise Missing(f"paper_figures.py: missing {args.runs} (no such folder of run folders)")
    extra = []
    if args.windows:
        extra = json.load(open(need(args.windows)))
        for w in extra:
            for k in ("name", "centre", "size"):
                if k not in w:
                    raise Missing(f"paper_figures.py: {args.windows}: a window lacks `{k}`")
    os.makedirs(args.out, exist_ok=True)
    fig4(args.runs, args.out)
    fig6(args.runs, args.out)
    fig8(args.runs, args.out)
    got_h = load_runs(args.runs, [c for c, _ in HEMI])
    got_t = load_runs(args.runs, [c for c, _ in TETRA])
    strain_maps(got_h, HEMI, "hemisphere", 160, args.out, extra)
    strain_maps(got_t, TETRA, "tetrahedron", 210, args.out, extra)
    fig10(got_h, got_t, args.out)
    fig_modes(got_h, got_t, args.out, extra)
    fig_stack(got_h, args.out, extra)
    total = sum(os.path.getsize(p) for p in written)
    print(f"# {len(written)} figures, {total / 1e6:.2f} MB")


if __name__ == "__main__":
    try:
        main()
    except Missing as e:
        sys.exit(str(e))
