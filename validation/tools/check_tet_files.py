"""Independent check of ergohand's tetrahedral files (.vtk legacy, .msh Gmsh 4.1).

Usage: python check_tet_files.py FILE.vtk|FILE.msh ...   (needs meshio, numpy; gmsh for .msh)

Each file is read by the readers an FE user has, never by ergohand's code: meshio for both
formats and the Gmsh SDK itself (`gmsh.open`) for .msh. A file fails unless:

- the node and tetrahedron counts the readers give equal the counts the file's own headers
  state (VTK `POINTS`/`CELLS`/`CELL_TYPES`, MSH `$Nodes`/`$Elements`);
- every tetrahedron's volume, recomputed here from its nodes, is positive, or the inverted
  ones are exactly those the file's `signed_volume` field flags (<= 0), and the field agrees
  with the recomputed volumes;
- the boundary triangles are the tetrahedra's free faces recomputed here (faces of exactly one
  tetrahedron, as many and the same), form a closed, consistently oriented 2-manifold (every
  edge in exactly two triangles, once each way) and face outward (their divergence volume is
  the tetrahedra's total);
- the groups exist with names: VTK integer cell data `link` and `boundary` with the names in
  the title line, MSH physical groups (`gmsh.model.getPhysicalGroups()`, each named; meshio's
  `cell_data["gmsh:physical"]` and `field_data`), a 3-D group for every tetrahedron and a 2-D
  group for every boundary triangle, each triangle in the group of the tetrahedron it bounds.

Prints one line per file and exits 1 on the first failing check of any file (all files are
checked).
"""

import re
import sys
from collections import Counter

import meshio
import numpy as np


class Fail(Exception):
    pass


def need(cond, msg):
    if not cond:
        raise Fail(msg)


def tet_volumes(points, tets):
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0


def free_faces(tets):
    """Faces of exactly one tetrahedron: {sorted face: tetrahedron index}."""
    count = Counter()
    owner = {}
    for t, q in enumerate(tets.tolist()):
        for f in ((q[1], q[2], q[3]), (q[0], q[2], q[3]), (q[0], q[1], q[3]), (q[0], q[1], q[2])):
            k = tuple(sorted(f))
            count[k] += 1
            owner[k] = t
    return {k: owner[k] for k, n in count.items() if n == 1}


def check_volumes(points, tets, field, what):
    vol = tet_volumes(points, tets)
    inverted = set(np.nonzero(vol <= 0)[0].tolist())
    need(field is not None and len(field) == len(tets), f"{what}: no signed_volume per tetrahedron")
    field = np.asarray(field, dtype=float).reshape(len(tets))
    flagged = set(np.nonzero(field <= 0)[0].tolist())
    need(inverted == flagged,
         f"{what}: {len(inverted)} tetrahedra have volume <= 0 recomputed, the file flags {len(flagged)}"
         f" (differing: {sorted(inverted ^ flagged)[:5]})")
    scale = max(np.abs(vol).max(), 1e-300)
    err = np.abs(field - vol).max()
    need(err <= 1e-6 * scale, f"{what}: signed_volume differs from the recomputed volume by {err:.3g}")
    return vol, len(inverted)


def check_boundary(points, tets, tris, vol, what):
    """Returns, per triangle, the tetrahedron it bounds."""
    free = free_faces(tets)
    keys = [tuple(sorted(f)) for f in tris.tolist()]
    need(len(tris) == len(free),
         f"{what}: {len(tris)} boundary triangles, but the tetrahedra have {len(free)} free faces")
    need(len(set(keys)) == len(keys), f"{what}: a boundary triangle is listed twice")
    missing = [k for k in keys if k not in free]
    need(not missing, f"{what}: {len(missing)} boundary triangles are not free faces, e.g. {missing[:1]}")
    directed = Counter()
    for f in tris.tolist():
        for k in range(3):
            directed[(f[k], f[(k + 1) % 3])] += 1
    need(all(n == 1 for n in directed.values()), f"{what}: a directed edge is used twice (not consistently oriented)")
    unmatched = [e for e in directed if (e[1], e[0]) not in directed]
    need(not unmatched, f"{what}: {len(unmatched)} boundary edges have one triangle (not closed), e.g. {unmatched[:1]}")
    a, b, c = (points[tris[:, k]] for k in range(3))
    enclosed = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    total = vol.sum()
    need(abs(enclosed - total) <= 1e-6 * abs(total),
         f"{what}: the boundary encloses {enclosed:.6g}, the tetrahedra {total:.6g} (not outward?)")
    return np.array([free[k] for k in keys])


def header_counts_vtk(text):
    pts = int(re.search(r"^POINTS (\d+)", text, re.M).group(1))
    cells = int(re.search(r"^CELLS (\d+)", text, re.M).group(1))
    m = re.search(r"^CELL_TYPES (\d+)\n", text, re.M)
    types = text[m.end():].split(None, int(m.group(1)))[: int(m.group(1))]
    return pts, cells, Counter(types)


def check_vtk(path):
    text = open(path, encoding="utf-8").read()
    n_pts, n_cells, types = header_counts_vtk(text)
    m = meshio.read(path)
    blocks = {b.type: (i, b.data) for i, b in enumerate(m.cells)}
    need(set(blocks) <= {"tetra", "triangle"}, f"{path}: unexpected cell types {set(blocks)}")
    tets = np.asarray(blocks["tetra"][1], dtype=np.int64)
    tris = np.asarray(blocks.get("triangle", (None, np.zeros((0, 3))))[1], dtype=np.int64)
    need(len(m.points) == n_pts, f"{path}: meshio reads {len(m.points)} nodes, POINTS says {n_pts}")
    need(len(tets) == types["10"], f"{path}: meshio reads {len(tets)} tetrahedra, CELL_TYPES lists {types['10']}")
    need(len(tets) + len(tris) == n_cells, f"{path}: {len(tets)} + {len(tris)} cells read, CELLS says {n_cells}")
    cd = m.cell_data
    ti = blocks["tetra"][0]
    vol, inverted = check_volumes(m.points, tets, cd.get("signed_volume", [None] * 9)[ti], path)
    need(len(tris) > 0, f"{path}: no boundary triangles")
    owner = check_boundary(m.points, tets, tris, vol, path)
    for name in ("link", "boundary"):
        need(name in cd, f"{path}: no cell data '{name}'")
    ri = blocks["triangle"][0]
    link_t, link_f = np.ravel(cd["link"][ti]), np.ravel(cd["link"][ri])
    need((np.ravel(cd["boundary"][ti]) == 0).all() and (np.ravel(cd["boundary"][ri]) == 1).all(),
         f"{path}: 'boundary' is not 0 on tetrahedra and 1 on triangles")
    need((link_f == link_t[owner]).all(), f"{path}: a boundary triangle's link is not its tetrahedron's")
    title = text.splitlines()[1]
    g = re.search(r"groups: (.*)$", title)
    need(g is not None, f"{path}: no group names in the title line")
    tok = g.group(1).split()
    names = dict(zip(map(int, tok[0::2]), tok[1::2]))
    used = set(link_t.tolist())
    need(used <= set(names), f"{path}: link ids {sorted(used - set(names))} have no name")
    return (f"{path}: OK (meshio {meshio.__version__}): {len(m.points)} nodes, {len(tets)} tetrahedra "
            f"({inverted} inverted, all flagged), {len(tris)} boundary triangles closed and outward, "
            f"{len(used)} links named")


def header_counts_msh(text):
    nodes = text[text.index("$Nodes") :].splitlines()[1].split()
    elems = text[text.index("$Elements") :].splitlines()[1].split()
    return int(nodes[1]), int(elems[1])


def check_msh(path):
    import gmsh

    text = open(path, encoding="utf-8").read()
    n_nodes, n_elems = header_counts_msh(text)
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(path)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        need(len(tags) == n_nodes, f"{path}: Gmsh reads {len(tags)} nodes, $Nodes says {n_nodes}")
        index = {int(t): i for i, t in enumerate(tags)}
        points = np.asarray(coords).reshape(-1, 3)
        tet_tags, tet_nodes = gmsh.model.mesh.getElementsByType(4)
        tri_tags, tri_nodes = gmsh.model.mesh.getElementsByType(2)
        need(len(tet_tags) + len(tri_tags) == n_elems,
             f"{path}: Gmsh reads {len(tet_tags)} + {len(tri_tags)} elements, $Elements says {n_elems}")
        tets = np.array([index[int(n)] for n in tet_nodes], dtype=np.int64).reshape(-1, 4)
        tris = np.array([index[int(n)] for n in tri_nodes], dtype=np.int64).reshape(-1, 3)
        # The signed volume view, by element tag.
        views = gmsh.view.getTags()
        need(len(views) >= 1, f"{path}: no signed_volume view")
        _, vtags, vdata, _, _ = gmsh.view.getModelData(views[0], 0)
        by_tag = {int(t): d[0] for t, d in zip(vtags, vdata)}
        field = [by_tag.get(int(t)) for t in tet_tags]
        need(None not in field, f"{path}: the signed_volume view misses tetrahedra")
        vol, inverted = check_volumes(points, tets, field, path)
        owner = check_boundary(points, tets, tris, vol, path)
        groups = gmsh.model.getPhysicalGroups()
        names = {g: gmsh.model.getPhysicalName(*g) for g in groups}
        need(all(names.values()), f"{path}: a physical group has no name")
        group_of = {}
        for dim, tag in groups:
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                for ty, etags, _ in zip(*gmsh.model.mesh.getElements(dim, ent)):
                    for e in etags:
                        need(int(e) not in group_of, f"{path}: element {e} in two physical groups")
                        group_of[int(e)] = names[(dim, tag)]
        tet_group = [group_of.get(int(t)) for t in tet_tags]
        tri_group = [group_of.get(int(t)) for t in tri_tags]
        need(None not in tet_group, f"{path}: a tetrahedron is in no physical group")
        need(None not in tri_group, f"{path}: a boundary triangle is in no physical group")
        need(all(tri_group[k] == "skin " + tet_group[owner[k]] for k in range(len(tris))),
             f"{path}: a boundary triangle's group is not 'skin' + its tetrahedron's")
        n3 = sum(1 for d, _ in groups if d == 3)
        n2 = sum(1 for d, _ in groups if d == 2)
    finally:
        gmsh.finalize()
    # meshio, the other reader an FE pipeline uses.
    m = meshio.read(path)
    counts = Counter()
    for b in m.cells:
        counts[b.type] += len(b.data)
    need(counts["tetra"] == len(tets) and counts["triangle"] == len(tris),
         f"{path}: meshio reads {dict(counts)}")
    phys = m.cell_data.get("gmsh:physical")
    need(phys is not None and all(len(p) == len(b.data) for p, b in zip(phys, m.cells)),
         f"{path}: meshio finds no gmsh:physical per cell")
    known = {int(v[0]) for v in m.field_data.values()}
    need({int(x) for p in phys for x in np.asarray(p)} <= known, f"{path}: meshio finds a physical tag without a name")
    return (f"{path}: OK (Gmsh {gmsh.__version__}, meshio {meshio.__version__}): {len(points)} nodes, "
            f"{len(tets)} tetrahedra ({inverted} inverted, all flagged), {len(tris)} boundary triangles "
            f"closed and outward, {n3} volume and {n2} surface physical groups named")


def main(files):
    if not files:
        print(__doc__.splitlines()[2], file=sys.stderr)
        return 2
    failed = False
    for f in files:
        try:
            print(check_msh(f) if f.endswith(".msh") else check_vtk(f))
        except Fail as e:
            print(f"FAIL {e}")
            failed = True
        except Exception as e:  # a reader refusing the file is a failure too
            print(f"FAIL {f}: {type(e).__name__}: {e}")
            failed = True
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
