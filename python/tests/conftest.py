import os
import pathlib
import subprocess

import pytest

import mgcloth

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli():
    """The mgcloth executable (CTest passes the one it built; by hand, build/bin/mgcloth)."""
    path = pathlib.Path(os.environ.get("MGCLOTH_CLI", ROOT / "build" / "bin" / "mgcloth"))
    if not path.exists():
        pytest.skip(f"no mgcloth executable at {path} (set MGCLOTH_CLI)")

    def run(*args, check=True):
        r = subprocess.run([str(path), *map(str, args)], capture_output=True, text=True)
        if check and r.returncode != 0:
            raise AssertionError(f"mgcloth {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stderr}")
        return r

    return run


@pytest.fixture(scope="session")
def small_grid():
    """A 0.5 m x 0.5 m cloth of 8 x 8 vertices; corners 0 and 7 are the two ends of its first row."""
    return mgcloth.grid(0.5, 0.5, 64)


def hanging(V, F, **kwargs):
    """The small cloth pinned at two corners, solved tightly enough that pins sit where they are pulled."""
    args = dict(threads=1, solver="newton-direct", rel_grad=1e-8, max_iters=100)
    args.update(kwargs)
    return mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, pins=[0, 7], pin_stiffness=1e5)], **args)
