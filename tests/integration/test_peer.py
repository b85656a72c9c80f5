"""The paper scene solved by an independent implementation of the same discrete problem: the
semismooth Newton solver written in GetFEM (benchmarks/performance/peer.py: its own assembly,
unknowns, Dirichlet elimination, memory recursion and Newton loop) gives contactvisco's contact
values (u_nu, the normal reaction p_nu + R_nu, the tangential reaction) at every node and
every state. Skipped where GetFEM's Python interface (python3-getfem) is not installed, and on
more than one rank (the peer is serial)."""
import importlib.util
import pathlib

import numpy as np
import pytest
from mpi4py import MPI

pytest.importorskip("getfem")

import contactvisco as cv  # noqa: E402

PEER = pathlib.Path(__file__).resolve().parents[2] / "benchmarks" / "performance" / "peer.py"


def load_peer():
    spec = importlib.util.spec_from_file_location("peer_benchmark", PEER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="the GetFEM peer is serial")
@pytest.mark.parametrize("predictor", ["extrapolate", "none"])
def test_getfem_peer_gives_the_same_contact_values(predictor):
    peer_module = load_peer()
    scene = cv.load_scene("paper", geometry={"cells": [12, 12]},
                          solver={"predictor": predictor})
    result = cv.solve(scene)
    peer = peer_module.GetfemPeer(scene, *peer_module.dolfinx_triangles(result))
    states = peer.run()
    assert len(states) == len(result.contact) == scene["time"]["steps"] + 1
    worst = peer_module.agreement(result, states, peer.x)
    assert max(worst.values()) < 1e-9, worst
    # Not a trivially agreeing state: at T the bottom edge has nodes on all three branches.
    final = states[-1]["values"]
    g = scene["contact"]["g"]
    assert np.any(final["u_nu"] <= 0.0)
    assert np.any((final["u_nu"] > 1e-6) & (final["u_nu"] < g - 1e-9))
    assert np.any(np.isclose(final["u_nu"], g, rtol=0, atol=1e-12))
    assert np.any(np.abs(final["sigma_tau"]) > 0.1)
