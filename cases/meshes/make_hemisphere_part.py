"""Writes hemisphere-part.inp: a structural shell mesh of the formed
hemisphere part, as a structural analyst would mesh it from the tool
surfaces (docs/export.md, "A worked example"): S4R quads on the punch's
sphere (radius 75 mm plus half the 0.3 mm ply, centred at the punch's
final centre, z = 0.3 mm) from the pole to 60 degrees, S3 triangles on the
flange (the die's top face plus half a ply, z = 0.15 mm) from 95 to 140 mm
radius; no mesh on the wall between them, where the ply bridges from the
punch to the die. Its own labels: nodes from 10001 in steps of 2,
elements from 501. Units: mm.

Usage: python3 make_hemisphere_part.py > hemisphere-part.inp
"""
import math

R, CENTRE_Z, FLANGE_Z = 75.15, 0.3, 0.15
nodes, quads, tris = [], [], []


def node(x, y, z):
    nodes.append((10001 + 2 * len(nodes), x, y, z))
    return nodes[-1][0]


# Cap: rings of constant polar angle, 48 around, 16 from the pole to 60°.
around, rings = 48, 16
pole = node(0.0, 0.0, CENTRE_Z - R)
ring_ids = []
for i in range(1, rings + 1):
    t = math.radians(60.0) * i / rings
    ring_ids.append([node(R * math.sin(t) * math.cos(2 * math.pi * j / around),
                          R * math.sin(t) * math.sin(2 * math.pi * j / around),
                          CENTRE_Z - R * math.cos(t)) for j in range(around)])
for j in range(around):
    tris.append((pole, ring_ids[0][j], ring_ids[0][(j + 1) % around]))
for i in range(rings - 1):
    a, b = ring_ids[i], ring_ids[i + 1]
    for j in range(around):
        quads.append((a[j], b[j], b[(j + 1) % around], a[(j + 1) % around]))
# Flange: 6 rings of 96 from 95 to 140 mm.
flange = [[node(r * math.cos(2 * math.pi * j / 96), r * math.sin(2 * math.pi * j / 96), FLANGE_Z)
           for j in range(96)] for r in [95.0 + 9.0 * k for k in range(6)]]
for i in range(5):
    a, b = flange[i], flange[i + 1]
    for j in range(96):
        k = (j + 1) % 96
        tris.append((a[j], b[j], b[k]))
        tris.append((a[j], b[k], a[k]))

print("** structural mesh of the formed hemisphere part (cases/meshes/make_hemisphere_part.py)")
print("** units: mm")
print("*NODE")
for n in nodes:
    print(f"{n[0]}, {n[1]:.6f}, {n[2]:.6f}, {n[3]:.6f}")
label = 501
print("*ELEMENT, TYPE=S4R, ELSET=CUP")
for q in quads:
    print(f"{label}, {q[0]}, {q[1]}, {q[2]}, {q[3]}")
    label += 1
print("*ELEMENT, TYPE=S3, ELSET=FLANGE_AND_POLE")
for t in tris:
    print(f"{label}, {t[0]}, {t[1]}, {t[2]}")
    label += 1
