"""Hostile and malformed input on the command line (run by hand:
python benchmarks/robustness/hostile_input.py).

Each case runs `contactvisco` in a fresh working folder and records the exit code, whether a
traceback was printed, whether any file appeared outside the output folder (or a marker file
an attack tries to create), the first line of the message and the wall time. The table goes to
benchmarks/results/hostile_input.md (and docs/reliability.md).
"""
import json
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # benchmarks/: common.py
from common import write_results  # noqa: E402
from helpers import run_cli  # noqa: E402


SMALL = ["--set", "geometry.cells=[4, 4]", "--set", "time.steps=2", "--quiet"]
MARKER = "PWNED"


def expression(text):
    return ["--set", f"traction.0.value=[0.0, {json.dumps(text)}]"]


CASES = [  # (input, arguments after 'contactvisco'; {out} is the output folder)
    ("attribute walk to a shell command",
     ["run", "paper", *expression("sin.__globals__['__builtins__']['__import__']('os')"
                                  f".system('touch {MARKER}')")]),
    ("`__import__('os').system(...)`",
     ["run", "paper", *expression(f"__import__('os').system('touch {MARKER}')")]),
    ("`().__class__.__base__.__subclasses__()`",
     ["run", "paper", *expression("().__class__.__base__.__subclasses__()")]),
    ("`open(...)`", ["run", "paper", *expression(f"open('{MARKER}', 'w')")]),
    ("lambda", ["run", "paper", *expression("(lambda: 1)()")]),
    ("comprehension", ["run", "paper", *expression("[c for c in (1, 2)][0]")]),
    ("`9**9**9`", ["run", "paper", *expression("9**9**9")]),
    ("60 nested unary minus", ["run", "paper", *expression("-" * 60 + "1")]),
    ("2001-character expression", ["run", "paper", *expression("1" + "+1" * 1000)]),
    ("`x[7]` in 2D", ["run", "paper", *expression("x[7]")]),
    ("contact.gap with a call", ["run", "hertz", "--set", "contact.gap='exec(1)'"]),
    ("scene file /dev/zero", ["run", "/dev/zero"]),
    ("geometry.script = absolute path", ["run", "hertz", "--set", "geometry.script='/tmp/x'"]),
    ("geometry.script = '../meshes/rectangle'",
     ["run", "hertz", "--set", "geometry.script='../meshes/rectangle'"]),
    ("geometry.file = a .geo file", ["file", "body.geo"]),
    ("geometry.file = 200 MB of zeros named .msh", ["zeros"]),
    ("ironing, geometry.parameters.h = 0", ["run", "ironing", "--set",
                                            "geometry.parameters.h=0"]),
    ("ironing, geometry.parameters.h = 1e-5", ["run", "ironing", "--set",
                                               "geometry.parameters.h=1e-5"]),
    ("hertz, radius = 0", ["run", "hertz", "--set", "geometry.parameters.radius=0"]),
    ("unknown script parameter", ["run", "ironing", "--set", "geometry.parameters.depth=1"]),
    ("name = '../escaped' (default output folder)", ["run", "paper", "--set",
                                                     "name='../escaped'", "--noout"]),
    ("name = '/tmp/abs'", ["run", "paper", "--set", "name='/tmp/abs'", "--noout"]),
    ("--out ''", ["run", "paper", "--out", "", "--noout"]),
    ("stray positional argument", ["run", "paper", "stray"]),
    ("time.steps = true", ["run", "paper", "--set", "time.steps=true"]),
    ("discretization.degree = true", ["run", "paper", "--set", "discretization.degree=true"]),
    ("output.xdmf = 1", ["run", "paper", "--set", "output.xdmf=1"]),
    ("--set material.E=5 on a scene with lambda, mu", ["lame"]),
    ("material.E = 1e-320", ["run", "paper", "--set", "material.E=1e-320"]),
    ("--set contact.g.x=1", ["run", "paper", "--set", "contact.g.x=1"]),
    ("--set dirichlet.7.value=1", ["run", "paper", "--set", "dirichlet.7.value=1"]),
    ("--set material=5", ["run", "paper", "--set", "material=5"]),
    ("paper rule at b = 2.6 (T = 10, 5 steps)",
     ["run", "paper", *SMALL, "--set", "time.T=10", "--set", "time.steps=5"]),
    ("the same with time.allow_unstable = true",
     ["run", "paper", *SMALL, "--set", "time.T=10", "--set", "time.steps=5", "--set",
      "time.allow_unstable=true"]),
    ("no Dirichlet condition, frictionless compliance contact",
     ["run", "paper", *SMALL, "--set", "dirichlet=[]", "--set", "contact.mu=0"]),
    ("hertz without its symmetry condition", ["run", "hertz", "--set", "dirichlet=[]",
                                              "--quiet"]),
    ("no Dirichlet condition, friction mu = 0.2 (documented: held)",
     ["run", "paper", *SMALL, "--set", "dirichlet=[]"]),
    ("probe outside the body", ["run", "paper", *SMALL, "--set",
                                "output.probes=[[0.5, 2.0]]"]),
    ("-ksp_type nonsense", ["run", "paper", *SMALL, "-ksp_type", "nonsense"]),
    ("-pc_factor_mat_solver_type nonsense (checked at the first solve)",
     ["run", "paper", *SMALL, "-pc_factor_mat_solver_type", "nonsense"]),
    ("-mat_mumps_icntl_14 abc", ["run", "paper", *SMALL, "-mat_mumps_icntl_14", "abc"]),
    ("solver.petsc_options.snes_rtol = 'abc'",
     ["run", "paper", *SMALL, "--set", "solver.petsc_options.snes_rtol='abc'"]),
    ("-snes_monitr (misspelled)", ["run", "paper", *SMALL, "-snes_monitr"]),
    ("Newton failure at step 0 (-snes_max_it 1)",
     ["run", "paper", *SMALL, "--set", "time.steps=1", "-snes_max_it", "1"]),
    ("plot on a cut summary.json", ["cut"]),
]


def run_case(label, args):
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        out = folder / "out"
        if args == ["zeros"]:
            with open(folder / "zeros.msh", "wb") as f:
                f.truncate(200 * 2**20)
            args = ["file", str(folder / "zeros.msh")]
        if args[0] == "file":
            (folder / "mesh.toml").write_text(
                f'[geometry]\ntype = "gmsh"\nfile = "{args[1]}"\n'
                '[[dirichlet]]\nboundary = "left"\n')
            args = ["run", str(folder / "mesh.toml")]
        elif args == ["lame"]:
            (folder / "lame.toml").write_text(
                '[material]\nmodel = "plane_strain"\nlambda = 57.7\nmu = 38.5\n'
                '[[dirichlet]]\nboundary = "left"\n')
            args = ["run", str(folder / "lame.toml"), "--set", "material.E=5"]
        elif args == ["cut"]:
            out.mkdir()
            (out / "summary.json").write_text('{"scene": {"name": "paper", "contact": {"g": 0.')
            args = ["plot", str(out)]
        if args[0] == "run":
            if "--noout" in args:
                args = [a for a in args if a != "--noout"]
            else:
                args = args + ["--out", str(out)]
        before = {p for p in folder.rglob("*")}
        tick = time.perf_counter()
        proc = run_cli(*args, cwd=folder, timeout=600)
        seconds = time.perf_counter() - tick
        outside = [p for p in folder.rglob("*") if p not in before and out not in p.parents
                   and p != out]
        escaped = (folder.parent / "escaped").exists()
        lines = [line for line in proc.stderr.splitlines() if line.startswith("contactvisco:")]
        message = lines[-1] if lines else proc.stderr.strip()[-300:]
    return dict(input=label, exit=proc.returncode, traceback="Traceback" in proc.stderr,
                outside=[str(p.relative_to(folder)) for p in outside] + (
                    ["../escaped"] if escaped else []), seconds=seconds, message=message)


def main():
    rows = [run_case(label, args) for label, args in CASES]
    lines = ["| input | exit | traceback | files outside --out | s | message |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        message = r["message"].replace("|", "\\|")
        if len(message) > 300:
            message = message[:300] + " ..."
        lines.append(f"| {r['input']} | {r['exit']} | {'yes' if r['traceback'] else 'no'} | "
                     f"{', '.join(r['outside']) or 'none'} | {r['seconds']:.1f} | {message} |")
    write_results("hostile_input", rows, lines)


if __name__ == "__main__":
    main()
