"""Every built-in scene: unknowns, steps, Newton iterations and wall time, on the ranks it is
started with (python for 1, mpirun -n 2 for 2).

    python benchmarks/performance/scenes.py
    mpirun -n 2 python benchmarks/performance/scenes.py
"""
import pathlib
import sys
from mpi4py import MPI

from contactvisco.scene import loader as scene_module

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import step_statistics, timed_run, write  # noqa: E402


def main():
    comm = MPI.COMM_WORLD
    rows = []
    for name in scene_module.builtin_names():
        scene = scene_module.load(name)
        seconds, result = timed_run(scene, comm)
        rows.append(dict(scene=name, ranks=comm.size, run_s=seconds,
                         **step_statistics(result)))
    if comm.rank == 0:
        write(f"scenes_np{comm.size}", rows,
              "| scene | ranks | unknowns (u + multipliers) | steps | Newton mean/max | "
              "s/step | run s | final sep/compl/bound |",
              lambda r: f"| {r['scene']} | {r['ranks']} | {r['unknowns']} ("
                        + " + ".join(str(v) for v in r["unknowns_by_field"].values())
                        + f") | {r['steps']} | {r['mean_newton']:.1f}/{r['max_newton']} | "
                        f"{r['s_per_step']:.4f} | {r['run_s']:.2f} | "
                        + "/".join(str(v) for v in r["final_status"].values()) + " |")


if __name__ == "__main__":
    main()
