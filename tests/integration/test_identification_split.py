"""Split communicators for a fit of several experiments (docs/identification.md,
fit.communicators): two creep experiments of the coarse sphere_creep (forces P and 2P), each
run by its own group of ranks; every rank gathers the residual and Jacobian blocks, so the
optimizer runs the same on every rank. On 2 ranks the split fit gives the parameters of the
fit of the same experiments on one rank (COMM_SELF), and a forward run that fails in one
group raises the same error on every rank instead of leaving the other group waiting."""
import numpy as np
import pytest
from mpi4py import MPI

from contactvisco.solver.newton import NewtonFailure
from contactvisco.studies import identification as ident

COARSE = ('geometry.parameters={radius = 10.0, height = 10.0, h_contact = 0.04, h_far = 3.0, '
          'refine = 0.3, growth = 0.15}')
MU0, FRACTION, P = 0.38461538461538464, 0.5, -0.0015
TIMES = [0.0, 0.25, 0.5, 1.0, 2.0]


def description(folder, communicators, extra=("", "")):
    """Two creep experiments (force P and 2P) and mu_0, the fraction 20 % off; their depths
    made by the forward model at the truth on COMM_SELF (the same on every rank)."""
    folder.mkdir(parents=True, exist_ok=True)
    experiments = ""
    for k, factor in enumerate((1.0, 2.0)):
        (folder / f"data{k}.csv").write_text("t,force,depth\n" + "".join(
            f"{t!r},{factor * P!r},0\n" for t in TIMES))
        experiments += (f'[[experiment]]\nscene = "sphere_creep"\ndata = "data{k}.csv"\n'
                        f"set = ['{COARSE}'{extra[k]}]\nnoise = 1e-5\n\n")
    (folder / "fit.toml").write_text(
        f'[fit]\ncommunicators = "{communicators}"\n\n' + experiments +
        '[[parameter]]\nkey = "viscoelastic.shear.instantaneous"\ninitial = 0.31\n'
        'bounds = [0.05, 2.0]\nscale = "log"\n\n'
        '[[parameter]]\nkey = "viscoelastic.shear.fractions.0"\ninitial = 0.4\n'
        'bounds = [0.05, 0.9]\n')
    spec = ident.read_fit(folder / "fit.toml")
    for e in spec["experiments"]:
        made = dict(e, set=[COARSE])
        e["depth"] = ident.forward(made, spec["parameters"], [MU0, FRACTION], MPI.COMM_SELF)
    return spec


def _folder(tmp_path_factory, name):
    # one folder for all ranks: rank 0 names it
    path = tmp_path_factory.mktemp(name) if MPI.COMM_WORLD.rank == 0 else None
    return MPI.COMM_WORLD.bcast(path, root=0) / f"rank{MPI.COMM_WORLD.rank}"


@pytest.mark.mpi
def test_a_split_fit_on_2_ranks_gives_the_parameters_of_1_rank(tmp_path_factory,
                                                               monkeypatch):
    """Split into one group per experiment (2 ranks, 2 experiments): mu_0 and the fraction
    equal those of the shared fit on one rank to 1e-10 relative, and the truth to 1e-6; the
    sub-communicator is freed when the fit ends."""
    comm = MPI.COMM_WORLD
    if comm.size != 2:
        pytest.skip("the split of 2 experiments over 2 ranks")
    folder = _folder(tmp_path_factory, "split")
    made = []

    class Recorded(ident._Groups):
        def __init__(self, *args):
            super().__init__(*args)
            made.append((self, self.sub))

    monkeypatch.setattr(ident, "_Groups", Recorded)
    split = ident.fit(description(folder / "split", "auto"), comm=comm)
    assert [g.count for g, _ in made] == [2]
    assert made[0][0].sub is None and made[0][1] == MPI.COMM_NULL     # freed
    assert split["communicators"] == {"mode": "auto", "groups": 2, "ranks": 2}
    one = ident.fit(description(folder / "one", "shared"), comm=MPI.COMM_SELF)
    assert one["communicators"]["groups"] == 1
    a = np.array([p["estimate"] for p in split["parameters"]])
    b = np.array([p["estimate"] for p in one["parameters"]])
    assert np.max(np.abs(a / b - 1)) < 1e-10
    assert np.max(np.abs(a / [MU0, FRACTION] - 1)) < 1e-6
    assert split["jacobian"]["rule"] == "sensitivities"
    # every rank holds the same report: the optimizer ran the same on both
    assert comm.allgather(a.tobytes()) == [a.tobytes()] * 2
    assert comm.allgather(split["evaluations"]) == [split["evaluations"]] * 2


@pytest.mark.mpi
def test_a_run_failing_in_one_group_fails_the_fit_on_every_rank(tmp_path_factory):
    """Experiment 1 with one Newton iteration per step and no step cuts fails on its group
    (rank 1); rank 0, whose experiment runs, raises the same NewtonFailure naming
    experiment[1], and the ranks go on talking to each other afterwards."""
    comm = MPI.COMM_WORLD
    if comm.size != 2:
        pytest.skip("the split of 2 experiments over 2 ranks")
    folder = _folder(tmp_path_factory, "failing")
    spec = description(folder, "split", ("", ", 'solver.max_cuts=0', "
                                             "'solver.petsc_options={snes_max_it = 1}'"))
    with pytest.raises(NewtonFailure) as caught:
        ident.fit(spec, comm=comm)
    text = "\n".join([str(caught.value), *getattr(caught.value, "__notes__", [])])
    assert "experiment[1]" in text
    assert comm.allreduce(1) == 2
