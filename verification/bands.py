#!/usr/bin/env python3
"""Fine-scale measures of a forming state that a mesh study needs beside its
means (docs/validation.md, "Mesh studies"): the transverse shear bands and
the flange's waves, each measured by itself, since they are different
effects (docs/theory.md, "13. Compaction of the fabric layer").

* `band_index(vtu, ...)`: the shear bands. In the ring of the blank between
  the die's opening and the flange (current horizontal radius from
  `inner` to `outer` mm), the area-weighted RMS of the element shear angle
  about its local mean (the area-weighted mean over the elements whose
  reference centroids lie within `smoothing` mm): bands of alternating
  shear a few cells wide make it large, a smooth field makes it small.
  A band width set by the mesh keeps it from converging under refinement.
* `flange_waves(vtu, ...)`: the flange's waves. The nodes whose current
  horizontal radius lies in [`inner`, `outer`] mm (the flat flange beyond
  the die's fillet), the RMS and the range of their heights about the
  median [mm]. On the paper's stiff penalty they are the wrinkles'
  heights; with a compliant layer they include the layer's compression
  (micrometres under the blankholder).

Usage: bands.py RUN_DIR [STATE]  (prints both measures of ply_NNNN.vtu)
"""

import argparse
import os

import meshio
import numpy as np
from scipy.spatial import cKDTree


def _state(path):
    """Points (current), reference points, triangles and cell data of a VTU."""
    mesh = meshio.read(path)
    current = np.asarray(mesh.points, dtype=float)
    reference = current - np.asarray(mesh.point_data["displacement"], dtype=float)
    triangles = next(c.data for c in mesh.cells if c.type == "triangle")
    cells = {k: np.asarray(v[0]) for k, v in mesh.cell_data.items()}
    return current, reference, triangles, cells


def band_index(path, inner=80.0, outer=110.0, smoothing=10.0):
    """The shear-band index [deg] of the ply state in `path` (module doc)."""
    current, reference, triangles, cells = _state(path)
    gamma = cells["shear_angle_deg"].astype(float)
    ref_c = reference[triangles].mean(axis=1)
    cur_c = current[triangles].mean(axis=1)
    e1 = reference[triangles[:, 1]] - reference[triangles[:, 0]]
    e2 = reference[triangles[:, 2]] - reference[triangles[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    radius = np.hypot(cur_c[:, 0], cur_c[:, 1])
    ring = np.where((radius >= inner) & (radius <= outer))[0]
    if ring.size == 0:
        return None
    tree = cKDTree(ref_c[:, :2])
    deviations = np.empty(ring.size)
    for k, e in enumerate(ring):
        near = tree.query_ball_point(ref_c[e, :2], smoothing)
        w = area[near]
        deviations[k] = gamma[e] - np.dot(w, gamma[near]) / w.sum()
    w = area[ring]
    return float(np.sqrt(np.dot(w, deviations ** 2) / w.sum()))


def flange_waves(path, inner=90.0, outer=150.0):
    """`(rms, peak_to_peak)` [mm] of the flange's heights: z of the nodes
    whose current horizontal radius lies in [inner, outer] mm, about their
    median (module doc)."""
    current, _, _, _ = _state(path)
    radius = np.hypot(current[:, 0], current[:, 1])
    z = current[(radius >= inner) & (radius <= outer), 2]
    if z.size == 0:
        return None, None
    return float(np.sqrt(np.mean((z - np.median(z)) ** 2))), float(z.max() - z.min())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("state", nargs="?", type=int, default=5)
    args = ap.parse_args()
    path = os.path.join(args.run, "vtu", f"ply_{args.state:04d}.vtu")
    if not os.path.exists(path):
        raise SystemExit(f"bands.py: {path} does not exist (a forming run folder's VTU state)")
    rms, spread = flange_waves(path)
    print(f"{path}: band index {band_index(path):.2f} deg; flange heights RMS "
          f"{rms:.4f} mm, range {spread:.4f} mm")


if __name__ == "__main__":
    main()
