"""Shared helpers of the package's tests: the repository, the command line, small cases."""

import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = ROOT / "target" / "release" / "membrane-contact"
CASES = ROOT / "data" / "cases"

# Membranes on the unit square, constant loads (their integrals against φ_a exact in any rule).
SMALL = {
    "title": "small",
    "mu1": 1.0,
    "mu2": 2.0,
    "f1": -20,
    "f2": 5,
    "g": "0.05",
    "mesh": {"kind": "rectangle", "n": 12},
}


def cli_solve(tmp_path, *args, name="cli"):
    """Runs the command line's solve; the fields of its solution.h5 (/mesh) and its attributes."""
    assert BIN.exists(), f"{BIN}: build it first (make build)"
    out = tmp_path / name
    subprocess.run([str(BIN), "solve", "--quiet", *map(str, args), "-o", str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    return h5(out)


def h5(directory):
    """(datasets of /mesh, attributes of /) of a result directory."""
    with h5py.File(Path(directory) / "solution.h5", "r") as f:
        data = {k: f["mesh"][k][()] for k in f["mesh"]}
        attrs = {k: f.attrs[k] for k in f.attrs}
    return data, attrs


def same_bits(a, b):
    """Equal bit for bit (same shape, same float64 values, NaN included)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def unit_square(n):
    """A structured mesh of the unit square, int32 triangles, counter-clockwise."""
    xs = np.linspace(0.0, 1.0, n + 1)
    points = np.array([[x, y] for y in xs for x in xs])
    triangles = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            b, c, d = a + 1, a + n + 1, a + n + 2
            triangles += [[a, b, d], [a, d, c]]
    return points, np.array(triangles, dtype=np.int32)


@pytest.fixture
def small():
    return {k: (dict(v) if isinstance(v, dict) else v) for k, v in SMALL.items()}
