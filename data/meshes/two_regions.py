"""Writes two_regions.msh (Gmsh MSH 4.1, ASCII): the mesh of two_regions.geo for machines without
Gmsh. The rectangle (0, 2) x (0, 1) cut by the segment x = 1 into the physical surfaces "loaded"
(x < 1) and "free" (x > 1); the physical curves "rim" (the side x = 2) and "clamped" (the other
sides). 16 x 8 cells, each cut along a diagonal that alternates, the interior vertices off x = 1
moved a little (deterministically) so that the mesh is not a grid; the interface x = 1 lies on
mesh edges, as Gmsh puts it (it is a curve of both surfaces).

    python3 data/meshes/two_regions.py            # rewrites data/meshes/two_regions.msh
"""
import math
import os

NX, NY = 16, 8
X0, X1, Y1 = 0.0, 2.0, 1.0


def node(i, j):
    return 1 + i + (NX + 1) * j


def main():
    coords = {}
    for j in range(NY + 1):
        for i in range(NX + 1):
            x, y = X0 + (X1 - X0) * i / NX, Y1 * j / NY
            inside = 0 < i < NX and 0 < j < NY
            if inside:
                dx, dy = (X1 - X0) / NX, Y1 / NY
                if i != NX // 2:
                    x += 0.18 * dx * math.sin(2.3 * i + 1.7 * j)
                y += 0.18 * dy * math.cos(1.9 * i - 2.9 * j)
            coords[node(i, j)] = (x, y)
    triangles = {1: [], 2: []}
    for j in range(NY):
        for i in range(NX):
            a, b, c, d = node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)
            cells = [(a, b, c), (a, c, d)] if (i + j) % 2 == 0 else [(a, b, d), (b, c, d)]
            triangles[1 if i < NX // 2 else 2].extend(cells)
    half = NX // 2
    # Curve entities: 1 bottom left, 2 bottom right, 3 right, 4 top right, 5 top left, 6 left, 7 cut.
    curves = {
        1: [(node(i, 0), node(i + 1, 0)) for i in range(half)],
        2: [(node(i, 0), node(i + 1, 0)) for i in range(half, NX)],
        3: [(node(NX, j), node(NX, j + 1)) for j in range(NY)],
        4: [(node(i + 1, NY), node(i, NY)) for i in range(half, NX)],
        5: [(node(i + 1, NY), node(i, NY)) for i in range(half)],
        6: [(node(0, j + 1), node(0, j)) for j in range(NY)],
        7: [(node(half, j), node(half, j + 1)) for j in range(NY)],
    }
    physical_curve = {1: 1, 2: 1, 3: 2, 4: 1, 5: 1, 6: 1}  # 1 clamped, 2 rim; the cut is in none
    physical_surface = {1: 3, 2: 4}  # 3 loaded, 4 free
    points = {1: (0, 0), 2: (1, 0), 3: (2, 0), 4: (2, 1), 5: (1, 1), 6: (0, 1)}
    curve_points = {1: (1, 2), 2: (2, 3), 3: (3, 4), 4: (4, 5), 5: (5, 6), 6: (6, 1), 7: (2, 5)}
    surface_curves = {1: (1, 7, 5, 6), 2: (2, 3, 4, -7)}
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames", "4",
           '1 1 "clamped"', '1 2 "rim"', '2 3 "loaded"', '2 4 "free"', "$EndPhysicalNames",
           "$Entities", "%d %d %d 0" % (len(points), len(curves), len(surface_curves))]
    for tag, (x, y) in points.items():
        out.append("%d %g %g 0 0" % (tag, x, y))
    for tag, (p, q) in curve_points.items():
        (xp, yp), (xq, yq) = points[p], points[q]
        phys = [physical_curve[tag]] if tag in physical_curve else []
        out.append("%d %g %g 0 %g %g 0 %d%s 2 %d %d" % (tag, min(xp, xq), min(yp, yq), max(xp, xq), max(yp, yq),
                                                       len(phys), "".join(" %d" % p for p in phys), p, -q))
    for tag, bounding in surface_curves.items():
        lo, hi = (0, 0) if tag == 1 else (1, 0), (1, 1) if tag == 1 else (2, 1)
        out.append("%d %g %g 0 %g %g 0 1 %d %d %s" % (tag, lo[0], lo[1], hi[0], hi[1], physical_surface[tag],
                                                      len(bounding), " ".join(str(c) for c in bounding)))
    out.append("$EndEntities")
    n = len(coords)
    out += ["$Nodes", "1 %d 1 %d" % (n, n), "2 1 0 %d" % n]
    out += [str(t) for t in sorted(coords)]
    out += ["%.17g %.17g 0" % coords[t] for t in sorted(coords)]
    out.append("$EndNodes")
    # As Gmsh saves a mesh with physical groups: only the elements of physical groups (not the cut's).
    blocks = ([(1, tag, 1, lines) for tag, lines in curves.items() if tag in physical_curve]
              + [(2, tag, 2, t) for tag, t in triangles.items()])
    count = sum(len(b[3]) for b in blocks)
    out += ["$Elements", "%d %d 1 %d" % (len(blocks), count, count)]
    tag = 1
    for dim, entity, kind, elements in blocks:
        out.append("%d %d %d %d" % (dim, entity, kind, len(elements)))
        for e in elements:
            out.append("%d %s" % (tag, " ".join(str(v) for v in e)))
            tag += 1
    out.append("$EndElements")
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "two_regions.msh")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")
    print("wrote %s: %d nodes, %d triangles" % (path, n, sum(len(t) for t in triangles.values())))


if __name__ == "__main__":
    main()
