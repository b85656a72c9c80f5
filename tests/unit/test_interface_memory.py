"""The memory of the closest-point search (interface.project): the slave nodes are compared
with every master facet in blocks, the block shrinking so that its temporaries stay within
interface._SEARCH_BYTES whatever the master's size, with the same answer."""
import tracemalloc

import numpy as np
import pytest

from contactvisco.fem import interface


def triangles(n):
    """The unit square z = 0 cut into n x n squares of two triangles each, as a Surface."""
    t = np.linspace(0.0, 1.0, n + 1)
    points = np.array([[x, y, 0.0] for y in t for x in t])
    cells = []
    for j in range(n):
        for i in range(n):
            a, b, c, d = (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1,
                          (j + 1) * (n + 1) + i)
            cells += [(a, b, c), (a, c, d)]
    cells = np.array(cells)
    return interface.Surface.from_arrays(points[cells], cells)


def nodes(count, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.random(count), rng.random(count), 0.05 * rng.random(count)])


def test_small_blocks_give_the_same_projection(monkeypatch):
    """A budget that leaves one node per block gives the very same facets, gaps and local
    coordinates as blocks of 256 (ties broken within each node's row)."""
    master, x = triangles(8), nodes(300)
    whole = interface.project(x, master, 0.2)
    monkeypatch.setattr(interface, "_SEARCH_BYTES", 1)
    single = interface.project(x, master, 0.2)
    assert np.array_equal(whole.facet, single.facet)
    assert np.array_equal(whole.gap, single.gap) and np.array_equal(whole.local, single.local)


@pytest.mark.parametrize("n", [16, 40])
def test_search_stays_within_its_budget(monkeypatch, n):
    """The peak the search allocates (tracemalloc), 512 and 3200 master triangles against 600
    nodes with a budget of 4 MiB: below the budget plus the surface itself; the budget is
    reached within a factor 4 (the pair's bytes are measured, not guessed far too high)."""
    budget = 4 * 2 ** 20
    monkeypatch.setattr(interface, "_SEARCH_BYTES", budget)
    master, x = triangles(n), nodes(600)
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    interface.project(x, master, 0.2)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    kept = master.coordinates.nbytes + master.nodes.nbytes + master.normals.nbytes
    print(f"{len(master.nodes)} triangles: peak {peak / 2**20:.2f} MiB (budget 4 MiB)")
    assert budget / 4 < peak < budget + kept
