"""The header line of a run names the linear solver the steps use: with the direct solver's
stale factorizations, steps whose Jacobian is close to the factorized one are solved on the
last factors, with the low-rank update of the changed rows (one sweep each: no Krylov
iterations printed) or by FGMRES (Krylov iterations printed), and the header says which."""
import json

import pytest
from mpi4py import MPI

from contactvisco import load_scene, solve
from contactvisco.solver import newton_base


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="reads what rank 0 prints")
@pytest.mark.parametrize("low_rank", [True, False], ids=["low_rank", "fgmres"])
def test_the_header_names_how_the_last_factors_are_used(capsys, monkeypatch, tmp_path,
                                                         low_rank):
    monkeypatch.setattr(newton_base, "LOW_RANK", low_rank)
    scene = load_scene("paper", geometry={"cells": [8, 8]}, time={"steps": 4},
                       output={"figures": False})
    solve(scene, tmp_path, progress=True)
    lines = capsys.readouterr().out.splitlines()
    header = next(line for line in lines if line.startswith("contactvisco: scene"))
    steps = [line for line in lines if line.startswith("step")]
    records = [json.loads(line) for line in (tmp_path / "steps.jsonl").read_text().splitlines()]
    setups = sum(r["preconditioner_setups"] for r in records)
    iterations = sum(r["newton_iterations"] for r in records)
    assert setups < iterations            # some Newton matrices were solved on earlier factors
    if low_rank:
        assert "preonly/lu, lu on the last factors with a low-rank update for <= " \
            f"{newton_base.LOW_RANK_ROWS} changed rows" in header, header
        assert not any("Krylov" in line for line in steps), steps
    else:
        assert f"preonly/lu, fgmres/lu on the last factors for <= {newton_base.STALE_ROWS} " \
            "changed rows" in header, header
        assert any("Krylov" in line for line in steps), steps
