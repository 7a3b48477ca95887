"""The package against the command line, its input forms, its errors, and its other entry points."""

import json
import os
import signal
import subprocess
import sys
import tomllib

import h5py
import meshio
import numpy as np
import pytest

import membrane_contact as mc
from conftest import BIN, CASES, ROOT, cli_solve, h5, same_bits, unit_square


def check_against_cli(result, data):
    assert same_bits(result.points, data["geometry"])
    assert np.array_equal(result.triangles, data["topology"])
    for name, values in result.fields.items():
        expected = data[name] == 1.0 if name == "contact" else data[name]
        assert same_bits(values, expected) if name != "contact" else np.array_equal(values, expected), name
    assert set(result.fields) == set(data) - {"geometry", "topology"}


def test_arrays_are_the_cli_fields_bit_for_bit(tmp_path):
    case = CASES / "default.toml"
    data, attrs = cli_solve(tmp_path, case, "--n", 16, "--estimate")
    r = mc.solve(case, n=16, estimate=True)
    check_against_cli(r, data)
    assert r.iterations == attrs["iterations"] and r.eta == attrs["estimator"]
    assert r.estimator.shape == (len(r.triangles),)


def test_obstacle_gives_u_and_psi(tmp_path):
    case = CASES / "ball.toml"
    data, _ = cli_solve(tmp_path, case, "--n", 16)
    r = mc.solve(str(case), n=16)
    check_against_cli(r, data)
    assert r.problem == "obstacle" and "u1" not in r.fields and r.u.shape == r.psi.shape
    assert r.contact.dtype == bool and r.contact.any()


def test_dict_toml_and_path_cases_agree(tmp_path):
    path = CASES / "default.toml"
    text = path.read_text()
    as_dict = tomllib.loads(text)
    results = [mc.solve(c, n=8) for c in (path, str(path), text, as_dict)]
    for r in results[1:]:
        assert same_bits(r.u1, results[0].u1) and same_bits(r.lambda_, results[0].lambda_)


def test_a_mistyped_path_is_named_as_a_path():
    # One line without "=" is a path, whatever its ending: the error names the file.
    for path in ("nope", "cases/defualt.toml", "data/cases/default.tom"):
        with pytest.raises(mc.InputError, match=f"^{path}: cannot read the case file"):
            mc.solve(path)


def test_meshio_pair_and_dolfinx_meshes_agree(small):
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 6, 6)
    points = msh.geometry.x
    triangles = msh.geometry.dofmap.array.reshape(-1, 3)
    assert triangles.dtype == np.int32
    m = meshio.Mesh(points, [("triangle", triangles.astype(np.int64))])
    from_dolfinx = mc.solve(small, msh)
    from_meshio = mc.solve(small, m)
    from_pair = mc.solve(small, (points[:, :2], triangles))
    for r in (from_meshio, from_pair):
        assert same_bits(r.u1, from_dolfinx.u1) and same_bits(r.gap, from_dolfinx.gap)
    # The given vertex numbering is kept.
    assert same_bits(from_dolfinx.points, points[:, :2])
    # Meshtags beside a dolfinx mesh are not read (they were "points need shape (N, 2)").
    with pytest.raises(mc.InputError, match="a dolfinx mesh is given alone"):
        mc.solve(small, (msh, None))


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda c: c.update(bogus=1), "unknown field `bogus`"),
        (lambda c: c.update(f1="1 +"), "key 'f1'"),
        # Beyond 64 bits: an OverflowError naming nothing.
        (lambda c: c["mesh"].update(n=2**70), "1180591620717411300000.0».*expected the cells per side"),
        (lambda c: c.update(mu1=10**5000), "case key 'mu1': an integer of 16610 bits is beyond"),
    ],
)
def test_bad_case_raises_input_error(small, change, message):
    change(small)
    with pytest.raises(mc.InputError, match=message) as e:
        mc.solve(small)
    assert isinstance(e.value, ValueError) and "\n" not in str(e.value)


def test_bad_mesh_raises_input_error(small):
    points, triangles = unit_square(3)
    degenerate = triangles.copy()
    degenerate[0] = [0, 1, 1]
    with pytest.raises(mc.InputError, match=r"triangle 0 \(near \(.*\)\) has zero area"):
        mc.solve(small, (points, degenerate))
    folded = points.copy()
    folded[5] = [0.9, 0.9]  # an interior vertex moved across its neighbours
    with pytest.raises(mc.InputError, match="the given mesh is not valid"):
        mc.solve(small, (folded, triangles))
    with pytest.raises(mc.InputError, match="refers to vertex -1"):
        bad = triangles.copy()
        bad[2, 0] = -1
        mc.solve(small, (points, bad))
    with pytest.raises(mc.InputError, match=f"triangle 3 refers to vertex {2**64 - 1},"):
        huge = triangles.astype(np.uint64)
        huge[3, 1] = 2**64 - 1
        mc.solve(small, (points, huge))


def test_meshio_points_no_triangle_uses_are_dropped_and_complex_points_refused(small):
    points, triangles = unit_square(6)
    # A node no triangle uses (a geometry point of a Gmsh file) at the front, shifting the numbers.
    extra = np.vstack([[[5.0, 5.0]], points])
    m = meshio.Mesh(extra, [("triangle", triangles + 1)])
    r = mc.solve(small, m)
    assert same_bits(r.points, points) and np.array_equal(r.triangles, triangles)
    assert same_bits(r.u1, mc.solve(small, (points, triangles)).u1)
    with pytest.raises(mc.InputError, match="vertex 0 belongs to no triangle"):
        mc.solve(small, (extra, triangles + 1))  # arrays keep their numbering: refused
    with pytest.raises(mc.InputError, match="points need real coordinates, got dtype complex128"):
        mc.solve(small, (points + 0j, triangles))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: mc.solve(refine=-1), "refine = -1: need a whole number ≥ 0"),
        (lambda: mc.solve(n=2.5), "n = 2.5: need a whole number ≥ 0"),
        (lambda: mc.solve(n=True), "n = True: need"),
        (lambda: mc.study(levels=[8, -16]), "levels = -16: need"),
        (lambda: mc.adapt(max_vertices=2**70), f"max_vertices = {2**70}: need"),
    ],
)
def test_bad_counts_raise_input_error(call, message):
    with pytest.raises(mc.InputError, match=message):
        call()


def test_cells_per_side_of_a_given_mesh_are_refused_with_what_to_do(small):
    with pytest.raises(mc.InputError, match=r"not to a mesh given as arrays: refine it instead .*refine=K"):
        mc.solve(small, unit_square(4), n=8)
    with pytest.raises(mc.InputError, match=r"not to a mesh given as arrays: give refinements instead"):
        mc.study(small, unit_square(4), levels=[8, 16])


def test_groups_of_a_gmsh_mesh_are_in_the_result(tmp_path):
    case = CASES / "two_regions.toml"
    data, attrs = cli_solve(tmp_path, case)
    r = mc.solve(case)
    mesh_data = {k: v for k, v in data.items() if not k.startswith("boundary_")}
    check_against_cli(r, mesh_data)
    assert r.places["group"] == "cells" and set(np.unique(r.group)) == {0.0, 1.0}
    assert json.loads(r.surface_groups) == ["loaded", "free"]
    for name in ("surface_groups", "curve_groups", "groups_source"):
        assert r.attributes[name] == attrs[name], name


def test_a_meshio_mesh_read_from_gmsh_keeps_its_physical_groups():
    # The groups of a meshio.Mesh read from the .msh file (gmsh:physical, field_data) carry the
    # case's data per group as the .msh path does: the same fields bit for bit.
    case = tomllib.loads((CASES / "two_regions.toml").read_text())
    msh = ROOT / "data" / "meshes" / "two_regions.msh"
    del case["mesh"]
    from_meshio = mc.solve(case, meshio.read(msh))
    from_path = mc.solve(dict(case, mesh={"kind": "file", "path": str(msh)}))
    assert same_bits(from_meshio.points, from_path.points)
    for name in ("u1", "u2", "lambda", "group"):
        assert same_bits(from_meshio.fields[name], from_path.fields[name]), name
    # Refinement and adaptivity keep them; a key the mesh does not have is named as such.
    table, _ = mc.adapt(case, meshio.read(msh), refine=1, steps=1)
    assert table[0]["vertices"] == len(mc.solve(case, meshio.read(msh), refine=1).points) > len(from_path.points)
    case["f1"] = {"upper": -20}
    with pytest.raises(mc.InputError, match="'upper' is not a physical surface of the given mesh"):
        mc.solve(case, meshio.read(msh))


def test_dolfinx_meshtags_written_by_dolfinx_are_groups(tmp_path):
    # dolfinx's own XDMFFile writes the mesh with cell tags (1: x < 1/2, 2: the rest) and facet
    # tags (5: x = 0, 7: the other sides); tables keyed by the tags give the fields of the same
    # data written with `if`, whose jump x = 1/2 lies on mesh edges.
    from dolfinx import io
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 8, 8)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    mid = msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, 3)].mean(axis=1)
    cell_tags = dmesh.meshtags(msh, 2, cells, np.where(mid[:, 0] < 0.5, 1, 2).astype(np.int32))
    cell_tags.name = "cell_tags"
    msh.topology.create_connectivity(1, 2)
    facets = dmesh.exterior_facet_indices(msh.topology)
    left = dmesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[0], 0.0))
    facet_tags = dmesh.meshtags(msh, 1, facets, np.where(np.isin(facets, left), 5, 7).astype(np.int32))
    facet_tags.name = "facet_tags"
    with io.XDMFFile(MPI.COMM_WORLD, str(tmp_path / "tagged.xdmf"), "w") as f:
        f.write_mesh(msh)
        f.write_meshtags(cell_tags)
        f.write_meshtags(facet_tags)
    mesh = {"kind": "file", "path": str(tmp_path / "tagged.xdmf")}
    case = {"mu1": 1.0, "mu2": 2.0, "f2": 5, "mesh": mesh}
    tabled = mc.solve(dict(case, f1={"1": -30, "2": "-5*y"}, g={"5": 0.05, "7": "0.05 + x*y"}))
    by_if = mc.solve(dict(case, f1="if(x < 0.5, -30, -5*y)", g="if(x > 0, 0.05 + x*y, 0.05)"))
    assert json.loads(tabled.surface_groups) == ["1", "2"] and json.loads(tabled.curve_groups) == ["5", "7"]
    assert np.allclose(tabled.u1, by_if.u1, rtol=0, atol=1e-14)
    assert np.allclose(tabled.fields["lambda"], by_if.fields["lambda"], rtol=0, atol=1e-12)
    # The tags matter: the loads swapped between the groups give another solution.
    swapped = mc.solve(dict(case, f1={"2": -30, "1": "-5*y"}, g={"5": 0.05, "7": "0.05 + x*y"}))
    assert np.abs(swapped.u1 - tabled.u1).max() > 1e-2


def test_threads_are_a_value_of_the_call_and_change_no_bit():
    # Large enough for the parallel paths (multigrid, blocks of the smoother, the norms' pieces).
    runs = {t: mc.solve(n=128, estimate=True, threads=t, verbose=True) for t in (1, 3)}
    for name in ("u1", "u2", "lambda", "estimator"):
        assert same_bits(runs[1].fields[name], runs[3].fields[name]), name
    assert runs[1].eta == runs[3].eta
    assert "on 1 thread," in runs[1].summary() and "on 3 threads," in runs[3].summary()
    for bad, need in ((0, "need a whole number ≥ 1"), (-1, "need a whole number ≥ 1"), (1025, "at most 1024 threads")):
        with pytest.raises(mc.InputError, match=f"threads = {bad}: {need}"):
            mc.solve(n=8, threads=bad)
    table, _ = mc.study(levels=[8, 16], threads=2)
    assert [row["vertices"] for row in table] == [81, 289]


def test_a_forked_process_solves_as_its_parent():
    # multiprocessing's fork (Linux's default before Python 3.14): in a child of a process that
    # had solved on its default threads, solve, write and read waited forever.
    code = (
        "import membrane_contact as mc, multiprocessing as mp, tempfile\n"
        "def work(n):\n"
        "    r = mc.solve(n=n)\n"
        "    with tempfile.TemporaryDirectory() as d:\n"
        "        r.write(d + '/out')\n"
        "        return float(mc.read(d + '/out').u1.sum())\n"
        "if __name__ == '__main__':\n"
        "    mine = work(16)\n"
        "    with mp.get_context('fork').Pool(2) as pool:\n"
        "        theirs = pool.map(work, [16, 16])\n"
        "    print(mine == theirs[0] == theirs[1])\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert run.stdout.strip() == "True", run.stderr


def test_what_is_not_a_result_directory_is_named(tmp_path):
    r = mc.solve(n=4)
    r.write(tmp_path / "out")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "adapt.xdmf").write_text("")
    (tmp_path / "run" / "step-002").mkdir()
    (tmp_path / "empty").mkdir()
    for path, message in [
        (tmp_path / "nope", "nope: no such directory"),
        (tmp_path / "out" / "solution.h5", "solution.h5 is a file: give the result directory"),
        (tmp_path / "run", "run is an adapt run: read one of its step directories, e.g. .*step-002"),
        (tmp_path / "empty", "empty: no solution.h5: not a result directory"),
    ]:
        with pytest.raises(mc.InputError, match=message):
            mc.read(path)


def test_obstacle_with_estimate_and_g2_with_estimate(tmp_path):
    r = mc.solve(CASES / "ball.toml", n=16, estimate=True, flux=True)
    assert r.eta >= r.error_energy and r.estimator.shape == (len(r.triangles),)
    data, attrs = cli_solve(tmp_path, CASES / "ball.toml", "--n", 16, "--estimate")
    assert r.eta == attrs["estimator"] and "estimator_obstacle" in attrs
    with pytest.raises(mc.InputError, match="not available yet"):
        mc.solve(CASES / "g2_lifted.toml", estimate=True)


def test_solver_error_and_output_error(small, tmp_path):
    small["solver"] = {"max_iterations": 1}
    with pytest.raises(mc.SolverError, match="did not converge"):
        mc.solve(small, start="cold")
    other = tmp_path / "not-a-result"
    other.mkdir()
    with pytest.raises(mc.OutputError, match="not a result of membrane-contact"):
        mc.solve(n=8).write(other)


def test_write_then_read_is_the_result(tmp_path):
    r = mc.solve(CASES / "default.toml", n=8, estimate=True, dual=True)
    r.write(tmp_path / "out")
    back = mc.read(tmp_path / "out")
    assert same_bits(back.points, r.points) and np.array_equal(back.triangles, r.triangles)
    assert set(back.fields) == set(r.fields)
    for name in r.fields:
        assert np.array_equal(back.fields[name], r.fields[name]), name
    assert back.attributes == r.attributes
    assert same_bits(back.dual_points, r.dual_points) and set(back.dual_fields) == set(r.dual_fields)
    assert all(same_bits(back.dual_fields[k], v) for k, v in r.dual_fields.items())
    # Its summary is the run's, and says it was read back.
    assert back.summary().startswith(r.summary().rsplit("seconds", 1)[0])
    assert "(read back: 81 vertices, 128 triangles)" in back.summary()
    # Written again from what was read, the file holds the same data.
    back.write(tmp_path / "again")
    assert all(same_bits(a, b) for a, b in zip(h5(tmp_path / "out")[0].values(), h5(tmp_path / "again")[0].values()))


def test_the_dual_submesh_and_fluxes_are_the_cli_s_bit_for_bit(tmp_path):
    # With flux=True, S_h and the fluxes t_ih are arrays of the result, as dual.xdmf holds them
    # (they were only written: `dual_fields` was a list of names); without, there are none.
    case = CASES / "default.toml"
    cli_solve(tmp_path, case, "--n", 8, "--flux")
    with h5py.File(tmp_path / "cli" / "solution.h5", "r") as f:
        written = {k: f["dual"][k][()] for k in f["dual"]}
    r = mc.solve(case, n=8, flux=True)
    assert same_bits(r.dual_points, written["geometry"])
    assert np.array_equal(r.dual_triangles, written["topology"])
    assert set(r.dual_fields) == set(written) - {"geometry", "topology"} >= {"lambda", "t1_x", "div_t2"}
    for name, values in r.dual_fields.items():
        assert same_bits(values, written[name]), name
    # 6 cells per triangle; λ_h constant on each D_a: the vertex value of its owner.
    assert r.dual_triangles.shape == (6 * len(r.triangles), 3)
    owner = r.dual_fields["vertex"].astype(np.int64)
    assert same_bits(r.dual_fields["lambda"], r.lambda_[owner])
    plain = mc.solve(case, n=8)
    assert (plain.dual_points, plain.dual_triangles, plain.dual_fields) == (None, None, {})


def test_study_returns_its_levels():
    table, results = mc.study(CASES / "default.toml", levels=[8, 16])
    assert [row["cells"] for row in table] == [8, 16]
    assert table[1]["h1_u1"] < table[0]["h1_u1"]
    assert [len(r.points) for r in results] == [row["vertices"] for row in table]


def test_adapt_returns_its_steps():
    table, results = mc.adapt(CASES / "default.toml", n=8, steps=2)
    assert len(table) == len(results) == 3
    assert [len(r.points) for r in results] == [row["vertices"] for row in table]
    assert table[-1]["vertices"] > table[0]["vertices"]
    # Why it stopped, as adapt.md says it (the loop ran to its step count here).
    assert [row["stopped"] for row in table] == [None, None, "the step count, 2"]
    table, _ = mc.adapt(CASES / "default.toml", n=8, target=1.0)
    assert len(table) == 1 and table[0]["stopped"].startswith("η = ") and "≤ the target 1e0" in table[0]["stopped"]


def test_adapt_with_dual_holds_s_h_as_the_command_line_writes_it(tmp_path):
    # adapt(dual=True): each step's S_h as arrays, bit for bit `adapt --dual`'s step files (the
    # keyword was missing); without it, none.
    table, results = mc.adapt(CASES / "default.toml", n=8, steps=1, dual=True)
    subprocess.run([str(BIN), "adapt", "--quiet", str(CASES / "default.toml"), "--n", "8", "--steps", "1",
                    "--dual", "-o", str(tmp_path / "cli")], check=True, stdout=subprocess.DEVNULL)
    with h5py.File(tmp_path / "cli" / "step-001" / "solution.h5", "r") as f:
        written = {k: f["dual"][k][()] for k in f["dual"]}
    last = results[-1]
    assert same_bits(last.dual_points, written["geometry"])
    assert set(last.dual_fields) == set(written) - {"geometry", "topology"}
    assert all(same_bits(v, written[k]) for k, v in last.dual_fields.items())
    assert mc.adapt(CASES / "default.toml", n=8, steps=1)[1][-1].dual_fields == {}


def test_summary():
    assert "active-set iterations" in mc.solve(n=8).summary()


def test_ctrl_c_interrupts_a_long_solve():
    code = (
        "import membrane_contact as mc, sys\n"
        "print('start', flush=True)\n"
        "try:\n"
        "    mc.solve(n=2048, estimate=True)\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted', flush=True); sys.exit(3)\n"
    )
    # A shell without job control starts background jobs with SIGINT ignored, and Python then
    # installs no KeyboardInterrupt: the child starts with the default handling, as at a terminal.
    p = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert p.stdout.readline().strip() == "start"
    import time

    time.sleep(2.0)
    sent = time.monotonic()
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=20)
    assert p.returncode == 3 and "interrupted" in out
    assert time.monotonic() - sent < 5.0


def test_the_example_runs():
    subprocess.run([sys.executable, str(ROOT / "examples" / "python" / "dolfinx_mesh.py")], check=True)


def test_the_readme_example_runs_as_written(tmp_path):
    """The README's Python example (its indented block from `import membrane_contact`), cut from
    README.md and run in an empty directory: it writes its result there."""
    text = (ROOT / "README.md").read_text().split("## Python", 1)[1]
    start = text.index("    import membrane_contact as mc")
    block = []
    for line in text[start:].splitlines():
        if line and not line.startswith("    "):
            break
        block.append(line[4:])
    run = subprocess.run([sys.executable, "-c", "\n".join(block)], cwd=tmp_path,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "active-set" in run.stdout
    assert (tmp_path / "mine" / "solution.h5").exists()


def test_a_missing_case_file_beside_a_mesh_is_named(tmp_path):
    points, triangles = unit_square(4)
    for case in ("nope.toml", tmp_path / "nope.toml", str(tmp_path)):
        with pytest.raises(mc.InputError, match="cannot read the case file"):
            mc.solve(case, (points, triangles))


def test_a_mesh_in_a_plane_z_constant_is_that_plane_s(small):
    # z = 5, or z = 0 up to a CAD kernel's round-off, is the plane's mesh (z != 0 was refused); a
    # tilted mesh is not.
    points, triangles = unit_square(4)
    flat = mc.solve(small, (points, triangles))
    for z in (np.full(len(points), 5.0), np.where(np.arange(len(points)) % 2 == 1, 1.2e-16, 0.0)):
        r = mc.solve(small, (np.column_stack([points, z]), triangles))
        assert same_bits(r.points, flat.points) and same_bits(r.u1, flat.u1)
    for z in (np.where(np.arange(len(points)) == 3, np.nan, 0.0), 1e15 + 100 * points[:, 0]):
        with pytest.raises(mc.InputError, match="the mesh must lie in a plane z = constant"):
            mc.solve(small, (np.column_stack([points, z]), triangles))
    tilted = np.column_stack([points, 0.5 * points[:, 0]])
    with pytest.raises(mc.InputError, match="point 1 has z = 0.125, the first z = 0.0: the mesh must lie in a plane"):
        mc.solve(small, (tilted, triangles))


def test_meshes_of_other_cells_are_refused(small):
    points, triangles = unit_square(4)
    quads = np.array([[0, 1, 6, 5]])
    mixed = meshio.Mesh(points, [("quad", quads), ("triangle", triangles[2:])])
    with pytest.raises(mc.InputError, match="quad cells are not supported"):
        mc.solve(small, mixed)
    # Lines (Gmsh's physical curves) are not cells of the domain: accepted.
    lines = meshio.Mesh(points, [("line", np.array([[0, 1]])), ("triangle", triangles)])
    assert len(mc.solve(small, lines).points) == len(points)
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    square = dmesh.create_unit_square(MPI.COMM_WORLD, 3, 3, dmesh.CellType.quadrilateral)
    with pytest.raises(mc.InputError, match="has quadrilateral cells"):
        mc.solve(small, square)
    # Two triangles of a P2 geometry (curved in general): refused, not read as a hanging node.
    import ufl

    x = np.array([[0, 0], [1, 0], [0, 1], [0.5, 0], [0.5, 0.5], [0, 0.5], [1, 1], [1, 0.5], [0.5, 1]], dtype=float)
    cells = np.array([[0, 1, 2, 3, 4, 5], [1, 6, 2, 7, 8, 4]], dtype=np.int64)
    curved = dmesh.create_mesh(MPI.COMM_WORLD, cells, x, ufl.Mesh(ufl.VectorElement("Lagrange", "triangle", 2)))
    with pytest.raises(mc.InputError, match="geometry has degree 2"):
        mc.solve(small, curved)


def test_a_given_mesh_replaces_the_named_mesh_and_the_tables_refine_refines_it(small):
    # As `[mesh] refine` refines a mesh file: a case written for the file, given the same mesh
    # in memory, solves on the same refined mesh (it was solved unrefined, silently).
    points, triangles = unit_square(4)
    named = mc.solve({**small, "mesh": {"kind": "file", "path": "x.msh", "refine": 1}}, (points, triangles))
    alone = mc.solve({**small, "mesh": {"refine": 1}}, (points, triangles))
    assert len(named.points) == len(alone.points) == 81
    assert same_bits(named.u1, mc.solve(small, (points, triangles), refine=1).u1)
    assert len(mc.solve({**small, "mesh": {"refine": 1}}, (points, triangles), refine=0).points) == 25
    with pytest.raises(mc.InputError, match="refine = -1.*whole number"):
        mc.solve({**small, "mesh": {"kind": "file", "path": "x.msh", "refine": -1}}, (points, triangles))
    # The table is checked as a case file's is, but for the file it names (replaced, not read).
    for mesh, error in (({"kind": "blob"}, "mesh.kind"), ({"bogus": 1}, "bogus"), ({"n": [4, 4]}, "kind")):
        with pytest.raises(mc.InputError, match=error):
            mc.solve({**small, "mesh": mesh}, (points, triangles))
    # An error elsewhere in a case file is placed in the file as written.
    text = "# a comment\n\nmu1 = 1.0\nmu2 = 1.0\nf1 = -1\nf2 = 1\ng = 0\n\n\nbogus = 2\n[mesh]\nkind = \"file\"\npath = \"x.msh\"\n"
    with pytest.raises(mc.InputError, match="line 10, column 1 .«bogus = 2»"):
        mc.solve(text, (points, triangles))


def test_result_arrays_are_read_only(small):
    r = mc.solve(small)
    with pytest.raises(ValueError):
        r.u1[:] = 7.0
    with pytest.raises(ValueError):
        r.points[0, 0] = 1.0


def test_the_interpreter_exits_cleanly_during_a_solve_in_another_thread():
    # A solve in a daemon thread when the script ends (or after Ctrl-C in the main thread): the
    # thread that waited for it took the GIL back every 50 ms, was ended by the exiting
    # interpreter (pthread_exit) and the process aborted ("FATAL: exception not rethrown").
    script = (
        "import membrane_contact as mc, threading, time\n"
        "threading.Thread(target=lambda: mc.solve(n=1024, threads=1), daemon=True).start()\n"
        "time.sleep(0.5)\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "FATAL" not in run.stderr, run.stderr


def test_a_result_is_written_to_a_directory_name_only(tmp_path, small):
    # As the command line refuses it: write("out.xdmf") made a directory named so.
    r = mc.solve(small, threads=1)
    for name in ("out.xdmf", "b.h5", "a.XDMF"):
        with pytest.raises(mc.OutputError, match="a result is a directory .*give a directory name"):
            r.write(tmp_path / name)
        assert not (tmp_path / name).exists()


def test_rayon_num_threads_is_checked_as_the_command_line_checks_it():
    # rayon ignores a value that is not a whole number (and ran one thread per core, silently).
    script = "import membrane_contact as mc\nmc.solve(n=8)\n"
    for value, error in (("abc", "RAYON_NUM_THREADS=abc: need a whole number"), ("2000", "RAYON_NUM_THREADS=2000: at most 1024 threads")):
        env = dict(os.environ, RAYON_NUM_THREADS=value)
        run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
        assert run.returncode == 1 and error in run.stderr, run.stderr
    env = dict(os.environ, RAYON_NUM_THREADS="abc")
    script = "import membrane_contact as mc\nprint(mc.solve(n=8, threads=1).vertices)\n"
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert run.stdout.strip() == "81", run.stderr


def test_the_summary_is_the_command_lines(tmp_path):
    # It lacked the line naming the case, which the command line prints first.
    summary = mc.solve(n=8, threads=1).summary()
    assert summary.startswith("case        built-in default case — Disk contact"), summary
    from conftest import BIN
    cli = subprocess.run([str(BIN), "solve", "--quiet", "--threads", "1", "--n", "8", "-o", str(tmp_path / "r")],
                         capture_output=True, text=True, check=True).stdout
    assert cli.splitlines()[:3] == summary.splitlines()[:3]


def test_results_pickle_whole_and_read_back_with_their_groups(tmp_path):
    import copy
    import pickle

    # Groups of a Gmsh file, the estimate and S_h: pickle raised TypeError on the native part,
    # and read → write lost the boundary edges' physical curves (in no field).
    r = mc.solve(CASES / "two_regions.toml", estimate=True, dual=True, threads=1)
    for back in (pickle.loads(pickle.dumps(r)), copy.deepcopy(r)):
        assert back.summary() == r.summary()
        assert set(back.fields) == set(r.fields) and set(back.dual_fields) == set(r.dual_fields)
        for name in r.fields:
            assert same_bits(back.fields[name], r.fields[name]), name
        for name in r.dual_fields:
            assert same_bits(back.dual_fields[name], r.dual_fields[name]), name
        assert same_bits(back.points, r.points) and np.array_equal(back.triangles, r.triangles)
        assert repr(sorted(back.attributes.items())) == repr(sorted(r.attributes.items()))
    r.write(tmp_path / "a")
    mc.read(tmp_path / "a").write(tmp_path / "b")
    with h5py.File(tmp_path / "a" / "solution.h5") as a, h5py.File(tmp_path / "b" / "solution.h5") as b:
        assert len(a["mesh/boundary_edges"]) > 0
        for name in ("mesh/boundary_edges", "mesh/boundary_group", "mesh/group"):
            assert np.array_equal(a[name][...], b[name][...]), name


def test_a_result_cannot_be_changed_in_place_but_copies_and_serializes():
    import copy
    import pickle

    r = mc.solve(n=4, threads=1)
    for array in (r.u1, r.u1.base):
        with pytest.raises(ValueError, match="cannot set WRITEABLE flag"):
            array.setflags(write=True)
    with pytest.raises(TypeError, match="read-only"):
        r.fields["u2"] = None
    with pytest.raises(TypeError, match="read-only"):
        r.attributes.update(iterations=-5)
    # Plain dicts to json, pickle and copy (a mappingproxy was none of them).
    assert json.loads(json.dumps(r.attributes))["iterations"] == r.attributes["iterations"]
    for back in (pickle.loads(pickle.dumps(r.attributes)), copy.deepcopy(r.attributes), dict(r.attributes)):
        assert type(back) is dict and back == r.attributes
    # Writing and reading take no RAYON_NUM_THREADS (the runs check it).
    code = (
        "import membrane_contact as mc, os, pickle, tempfile\n"
        "r = mc.solve(n=4, threads=1)\n"
        "d = tempfile.mkdtemp()\n"
        "r.write(d + '/out'); mc.read(d + '/out'); pickle.loads(pickle.dumps(r))\n"
        "print('ok')\n"
    )
    env = dict(os.environ, RAYON_NUM_THREADS="abc")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert run.stdout.strip() == "ok", run.stderr
