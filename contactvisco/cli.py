"""The `contactvisco` command.

    contactvisco run SCENE [--out DIR] [--set key=value ...] [PETSc options]
    contactvisco scenes
    contactvisco show SCENE [--all] [--set key=value ...]
    contactvisco check SCENE [--set key=value ...] [PETSc options]
    contactvisco plot DIR [--format png|pdf|svg] [--dpi N] [--times T ...] [--edges]
    contactvisco tradeoff SCENE --target TOL [--out DIR] [--budget SECONDS] [--measure NAME]
    contactvisco --version

SCENE is a built-in scene name or a TOML file. Arguments that start with a single dash and are
not ours (-snes_monitor, -ksp_type gmres, ...) go to PETSc.
"""

from __future__ import annotations

import argparse
import signal
import sys

from contactvisco.errors import SceneError

EXAMPLES = """examples:
  contactvisco scenes                                  the built-in scenes
  contactvisco show paper > my_scene.toml              a scene as TOML, to edit and run
  contactvisco check my_scene.toml                     build it, check it, say its size
  contactvisco run my_scene.toml --out results/mine    solve it (figures in results/mine)
  contactvisco run paper --set time.steps=100 --set contact.mu=0.4
  contactvisco run paper -snes_monitor -ksp_view       single-dash options go to PETSc
  mpirun -n 4 contactvisco run paper --out results/np4
  contactvisco run paper --out results/paper --restart after a stop: from the checkpoint
  contactvisco plot results/paper --times 0.5          redraw the figures
  contactvisco fit my_fit.toml --out results/fit       identify parameters from curves
exit codes: 0 done, 2 scene, folder or option error, 3 a step (or a fit) that does not converge,
  128 + N stopped by signal N, 1 anything else"""


def _scene_arguments(parser) -> None:
    """SCENE and --set, as every command that reads a scene takes them."""
    parser.add_argument("scene", help="built-in scene name or TOML file")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scene value, e.g. --set time.steps=100")


def _parser():
    parser = argparse.ArgumentParser(
        prog="contactvisco", epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Quasistatic frictional contact of viscoelastic bodies with long memory "
                    "(Ouafik 2024) in DOLFINx.")
    parser.add_argument("--version", action="store_true",
                        help="print the versions of contactvisco, DOLFINx, PETSc and MPI")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run(sub)
    sub.add_parser("scenes", help="list the built-in scenes")
    _add_plot(sub)
    _add_tradeoff(sub)
    _add_show_and_check(sub)
    _add_relaxation(sub)
    _add_fit(sub)
    return parser


def _add_fit(sub) -> None:
    fit = sub.add_parser("fit", help="identify material parameters from indentation curves",
                         description="Fit the parameters of a fit description (TOML: "
                         "experiments of a scene and a CSV curve each, the scene keys to "
                         "identify) by weighted least squares with the solver in the loop; "
                         "write fit.json, curves.csv and the figures fit.png, fit_moduli.png, "
                         "fit_correlation.png. Exit 3 if the optimizer "
                         "stops before converging (the last state written).")
    fit.add_argument("description", help="the fit description (TOML)")
    fit.add_argument("--out", default="results/fit", help="the output folder (default: "
                     "results/fit)")


def _add_relaxation(sub) -> None:
    relax = sub.add_parser("relaxation", help="draw the relaxation, storage and loss moduli "
                           "of a scene's [viscoelastic] material",
                           description="Draw phi(t), E'(w) and E''(w) of the Prony series of "
                           "a scene's [viscoelastic] table, at T_ref and shifted to other "
                           "temperatures (master curves).")
    _scene_arguments(relax)
    relax.add_argument("--temperature", type=float, action="append", default=[],
                       help="also draw the curves at this temperature (repeatable)")
    relax.add_argument("--out", default="relaxation.png", help="the figure file "
                       "(default: relaxation.png)")


def _add_run(sub) -> None:
    run = sub.add_parser("run", help="solve a scene", description="Solve a scene. Arguments "
                         "that start with a single dash (-snes_monitor, -ksp_type gmres, ...) "
                         "go to PETSc.")
    _scene_arguments(run)
    run.add_argument("--out", default=None, help="output folder (default results/<scene name>)")
    run.add_argument("--preset", choices=["fast", "balanced", "accurate"],
                     help="speed-accuracy preset (scales the scene's mesh and steps)")
    verbosity = run.add_mutually_exclusive_group()
    verbosity.add_argument("--quiet", action="store_true", help="no progress output")
    # -v is read as --verbose before argparse sees it: declared as a short option, argparse
    # would take PETSc options that start with -v (-vec_type) for -v with a value.
    verbosity.add_argument("--verbose", action="store_true",
                           help="(or -v) print also the residual |F| of every Newton "
                           "iteration")
    run.add_argument("--overwrite", action="store_true",
                     help="replace the files of an earlier run in --out")
    run.add_argument("--restart", action="store_true",
                     help="continue the run in --out from its last checkpoint")
    run.add_argument("--allow-large-output", action="store_true",
                     help="run even when the output is estimated above output.max_bytes "
                     "(same as --set output.max_bytes=inf)")
    run.add_argument("--traceback", action="store_true",
                     help="show the Python traceback of an unexpected error")


def _add_plot(sub) -> None:
    plot = sub.add_parser("plot", help="redraw the figures of a finished run")
    plot.add_argument("folder", help="a run's output folder")
    plot.add_argument("--format", choices=["png", "pdf", "svg"], default="png",
                      help="file format of the figures (default png)")
    plot.add_argument("--dpi", type=int, default=150,
                      help="resolution of raster output (default 150; 300 or more for print)")
    plot.add_argument("--times", type=float, nargs="+", default=None, metavar="T",
                      help="draw the figures at these times, each named with the time it "
                      "shows (stress_t0.5.png); where no state was kept at a time, the "
                      "nearest is drawn and said (default: the figures at T)")
    plot.add_argument("--edges", action="store_true", help="draw the mesh edges on the "
                      "stress map")


def _add_tradeoff(sub) -> None:
    trade = sub.add_parser("tradeoff", help="error against wall time over a ladder of "
                           "discretizations; the cheapest settings that reach a target")
    _scene_arguments(trade)
    trade.add_argument("--target", type=float, required=True, metavar="TOL",
                       help="relative error to reach, e.g. 0.01")
    trade.add_argument("--out", default=None, help="output folder (default "
                       "results/tradeoff-<scene name>)")
    trade.add_argument("--budget", type=float, default=float("inf"), metavar="SECONDS",
                       help="bound on the total time: no run starts whose predicted time "
                       "exceeds what is left")
    trade.add_argument("--measure", default="contact_pressure",
                       choices=["contact_pressure", "contact_displacement", "probe"],
                       help="the error measure (default contact_pressure)")
    trade.add_argument("--levels", type=int, default=4, help="mesh levels (default 4)")
    trade.add_argument("--coarsest", type=float, default=0.25, help="mesh scale of the "
                       "coarsest level relative to the scene's (default 0.25)")
    trade.add_argument("--degrees", default="1,2", help="Lagrange degrees tried (default 1,2)")


def _add_show_and_check(sub) -> None:
    show = sub.add_parser("show", help="print a scene as TOML that run accepts")
    _scene_arguments(show)
    show.add_argument("--all", action="store_true", help="every key, defaults included "
                      "(default: what the scene sets)")
    check = sub.add_parser("check", help="build a scene and make every check a run makes, "
                           "without solving; print its size", description="Build a scene's "
                           "mesh, forms and solver and check them as a run does, without "
                           "solving. Exit 0 if the scene can run, 2 if not. Single-dash "
                           "arguments go to PETSc, as for run.")
    _scene_arguments(check)
    check.add_argument("--preset", choices=["fast", "balanced", "accurate"])


def main(argv=None):
    """The command; SIGINT and SIGTERM outside the time loop (start-up, figures) end it at
    once with one line and exit 128 + the signal number, never a traceback."""
    from contactvisco.io import parallel
    previous = parallel.stop_at_once()
    try:
        return _main(argv)
    except BaseException as caught:
        err = parallel.interrupted_by(caught)       # Python may wrap it in a RuntimeError
        if err is None:
            raise
        signum = getattr(err, "signum", signal.SIGINT)
        if not getattr(err, "reported", False) and parallel.first_rank():
            print(f"contactvisco: stopped by {signal.Signals(signum).name}", file=sys.stderr,
                  flush=True)
        return 128 + signum
    finally:
        if argv is None:                  # the command is the process: it ends here
            _before_exit()
        else:
            parallel.restore_signals(previous)


def _before_exit():
    """Move every object left to the garbage collector's permanent generation (gc.freeze):
    the interpreter's shutdown then frees them by their reference counts, without the full
    collections that trace every object of DOLFINx, UFL, PETSc and matplotlib (about a second
    of a `run` with figures on this machine, `benchmarks/performance/startup.py`). The run's
    files are closed by then (its writer, lock and figures close theirs before returning).

    The exit status is decided here, so SIGINT and SIGTERM are ignored from now on: the
    interpreter's shutdown puts the default handlers back, and a signal in its last
    milliseconds would otherwise turn a finished command into one killed by that signal."""
    import gc
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)
    gc.freeze()


def _main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--version"]:
        print(versions())
        return 0
    argv = ["--verbose" if a == "-v" else a for a in argv]
    args, petsc_args = _parser().parse_known_args(argv)
    bad = [a for a in petsc_args if a.startswith("--")]
    if bad:
        _parser().error(f"unrecognized arguments: {' '.join(bad)}")
    # A word that follows no -option is no PETSc value: a stray argument.
    stray = [a for i, a in enumerate(petsc_args) if not a.startswith("-")
             and (i == 0 or not petsc_args[i - 1].startswith("-"))]
    if stray or (petsc_args and args.command not in ("run", "check")):
        _parser().error(f"unrecognized arguments: {' '.join(stray or petsc_args)}")
    if getattr(args, "out", None) == "":
        _parser().error("--out needs a folder name (leave it out for results/<scene name>)")
    # PETSc reads its command line only if told before anything imports it. A signal during
    # the native start-up of PETSc and DOLFINx is held back until it is complete.
    from contactvisco.io import parallel
    with parallel.signals_deferred():
        import petsc4py
        petsc4py.init([sys.argv[0]] + petsc_args)
        if args.command in ("run", "check", "tradeoff"):
            import dolfinx  # noqa: F401

    from contactvisco import api
    from contactvisco.scene import loader as scene_module
    if args.command == "plot":
        return _plot(args)
    if args.command == "tradeoff":
        return _tradeoff(args)
    if args.command == "run":
        return _run(args, petsc_args, scene_module)
    if args.command == "check":
        return _check(args)
    if args.command == "relaxation":
        return _relaxation(args)
    if args.command == "fit":
        return _fit(args)
    # Printing commands end quietly when their reader does (`show paper | head`).
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    try:
        if args.command == "scenes":
            for name, description in api.builtin_scenes().items():
                print(f"{name:12s} {description}")
            return 0
        scene = api.load_scene(args.scene, sets=args.set)
        print(api.scene_toml(scene, every_value=args.all), end="")
        print(_grid_comment(scene))
        return 0
    except SceneError as err:
        print(f"contactvisco: scene error: {err}", file=sys.stderr)
        return 2


def _grid_comment(scene) -> str:
    """A TOML comment that says what the time grid makes: its steps and their extremes."""
    from contactvisco.model import time_grid
    steps, least, largest = time_grid.summary(scene["time"])
    if time_grid.adaptive(scene["time"]):       # chosen as the run goes: its bounds
        return (f"\n# time grid (adaptive): at least {steps} steps, k between {least:.4g} "
                f"and {largest:.4g}, tolerance {scene['time']['tolerance']:g}")
    return (f"\n# time grid ({scene['time']['grid']}): {steps} steps, k from {least:.4g} to "
            f"{largest:.4g}")


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000


def _check(args) -> int:
    """`contactvisco check`: every rank builds; one report or one error message."""
    from mpi4py import MPI

    from contactvisco import api
    from contactvisco.io import parallel
    comm = MPI.COMM_WORLD
    parallel.prepare(comm)
    preset = [f"preset='{args.preset}'"] if args.preset else []
    try:
        scene = api.load_scene(args.scene, sets=preset + args.set)
        report = api.check(scene, comm=comm)
    except SceneError as err:
        return parallel.fail_together(comm, 2, f"contactvisco: scene error: {err}", err)
    except Exception as err:
        return parallel.fail_together(comm, 1, f"contactvisco: error: {_describe(err, None)}",
                                      err)
    if comm.rank == 0:
        unknowns = ", ".join(f"{name} {count}" for name, count in report["unknowns"].items())
        b = report["stability_number"]
        print(f"scene '{scene['name']}': checks passed on {comm.size} rank(s)\n"
              f"  mesh: {report['cells']} cells, {report['vertices']} vertices; "
              f"{report['contact_nodes']} contact nodes\n"
              f"  unknowns: {unknowns}\n"
              f"  linear system: {report['linear_system']}, {report['linear_solver']}\n"
              f"  time grid: {scene['time']['grid']}, {report['steps']} steps, k from "
              f"{report['smallest_step']:.4g} to {report['largest_step']:.4g}\n"
              f"  time rule: {scene['time']['rule']}, "
              + _rule_stability(scene, report, b) + "\n"
              f"  memory of the history at the last step: {_size(report['history_bytes'])}\n"
              f"  output (estimate, figures left out): {_size(report['output_bytes'])}"
              + (f" (above output.max_bytes = {_size(scene['output']['max_bytes'])}: the run "
                 "will be refused without --allow-large-output)"
                 if report["output_bytes"] > scene["output"]["max_bytes"] else ""))
    return 0


def _rule_stability(scene, report, b: float) -> str:
    """What bounds the step of the time rule: the paper's rule its number b (stable below 1);
    the trapezoid rule (and the exponential rule with a constant or fractional kernel) the
    smallest stiffness of a step A + w P per mode, > 0; the exponential rule of relaxing terms
    nothing (the step's stiffness >= the long-term modulus)."""
    if scene["time"]["rule"] == "paper":
        body = report.get("stability_body")
        return (f"b = k R(0) (1 + nu) / E = {b:.3g}"
                + (f" (body {body!r}, the largest of the bodies)" if body else "")
                + (" (unstable: the run will warn)" if report["unstable"] else ""))
    if report["unconditionally_stable"]:
        return ("unconditionally stable (each exponential integrated exactly: the step's "
                "stiffness stays above the long-term modulus for every k)")
    margins = report["implicit_stiffness"]
    if not margins:
        return "no memory: stable for every k"
    names = {"deviatoric": "2 mu", "volumetric": "d lambda + 2 mu"}
    parts = [f"{mode} {least:.3g} ({names[mode]} = {elastic:.3g})"
             for mode, (least, elastic) in margins.items()]
    lost = any(least <= 0.0 for least, _ in margins.values())
    return ("smallest stiffness of a step A + w P (w the implicit weight of eps_n+1): "
            + ", ".join(parts)
            + (": not > 0, a step loses its stiffness (take smaller steps)" if lost
               else ": > 0, stable for this k"))


def versions() -> str:
    """What a bug report needs: the versions of this package and of the stack under it."""
    from importlib import metadata

    import dolfinx
    import mpi4py
    from mpi4py import MPI
    from petsc4py import PETSc

    import pathlib

    import contactvisco
    from contactvisco import __version__
    from contactvisco.fem import compat
    petsc = ".".join(str(v) for v in PETSc.Sys.getVersion())
    library = MPI.Get_library_version().strip().splitlines()[0]
    try:
        gmsh = metadata.version("gmsh")
    except metadata.PackageNotFoundError:
        import gmsh as gmsh_module
        gmsh = getattr(gmsh_module, "__version__", "unknown")
    return "\n".join([
        f"contactvisco {__version__} (from {pathlib.Path(contactvisco.__file__).parent})",
        f"DOLFINx {dolfinx.__version__} (Python {sys.version.split()[0]})",
        f"PETSc {petsc} (hypre: {'yes' if compat.has_hypre() else 'no'}, MUMPS: "
        f"{'yes' if PETSc.Sys.hasExternalPackage('mumps') else 'no'})",
        f"MPI: {library} (mpi4py {mpi4py.__version__})",
        f"gmsh {gmsh}",
    ])


def _progress(args):
    """solve's progress: False (--quiet), True, or "verbose" (--verbose)."""
    return False if args.quiet else "verbose" if args.verbose else True


def _run(args, petsc_args, scene_module):
    """`contactvisco run`: every error, on any rank, ends every rank with one message
    (contactvisco.io.parallel): exit 2 for a scene or folder error, 3 for a Newton failure,
    128 + signal for SIGINT/SIGTERM, 1 for anything else."""
    from mpi4py import MPI
    from contactvisco import api
    from contactvisco.io import parallel
    comm = MPI.COMM_WORLD
    parallel.prepare(comm)
    out = args.out
    preset = [f"preset='{args.preset}'"] if args.preset else []
    allow = ["output.max_bytes=inf"] if args.allow_large_output else []
    # An error on one rank alone ends every rank from inside the run, with these words.
    parallel.describe_with(lambda err: _outcome(err, args, out))
    try:
        scene = api.load_scene(args.scene, sets=preset + args.set + allow)
        out = args.out or f"results/{scene['name']}"
        _check_writable(out)
        api.solve(scene, out, comm=comm, progress=_progress(args), restart=args.restart,
                  overwrite=args.overwrite, keep_contact=False)
    except Exception as err:              # no bare traceback for users; --traceback shows it
        interrupt = parallel.interrupted_by(err)
        if interrupt is not None:         # wrapped by Python in another error
            raise interrupt from None
        return parallel.fail_together(comm, *_outcome(err, args, out), err)
    finally:
        parallel.describe_with(None)
    from contactvisco.solver.newton import unused_options
    unused = unused_options(petsc_args)
    if unused and comm.rank == 0:
        print(f"contactvisco: warning: PETSc options no solver used: {', '.join(unused)} "
              "(misspelled, or for a solver this scene does not use)", file=sys.stderr)
    return 0


def _outcome(err: Exception, args, out) -> tuple[int, str]:
    """The exit code and message of `run` for an error: 2 for a scene or folder error, 3 for
    a Newton failure, 128 + N for a stop by signal N, 1 for anything else."""
    from contactvisco.io import parallel
    from contactvisco.solver.newton import NewtonFailure
    if isinstance(err, SceneError):
        from contactvisco.io.files import Damaged
        from contactvisco.io.files import UnsafeEntry
        from contactvisco.io.lock import FolderError
        from contactvisco.io.output import DamagedFile
        kind = "error" if isinstance(err, (Damaged, FolderError, UnsafeEntry, DamagedFile)) \
            else "scene error"
        return 2, f"contactvisco: {kind}: {err}"
    if isinstance(err, NewtonFailure):
        return 3, f"contactvisco: {err}"
    if isinstance(err, parallel.Stopped):
        return err.exit_code, f"contactvisco: {err}"
    if args.traceback:
        import traceback
        traceback.print_exception(err)
    return 1, (f"contactvisco: error: {_describe(err, out)} (run again with --traceback for "
               "the details)")


def _describe(err: Exception, out) -> str:
    """What went wrong; for an OSError the file, or else the output folder being written."""
    if isinstance(err, OSError) and err.strerror:
        where = err.filename or (f"writing into {out}" if out else None)
        return f"{type(err).__name__}: {err.strerror}" + (f" ({where})" if where else "")
    return f"{type(err).__name__}: {err}"


def _check_writable(folder):
    """Fail before any work if the output folder cannot be written."""
    import pathlib
    import tempfile
    path = pathlib.Path(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path):
            pass
    except OSError as err:
        raise SceneError(f"output folder '{folder}' is not writable: {err.strerror}") from None


def _relaxation(args) -> int:
    """`contactvisco relaxation`: the moduli of a [viscoelastic] material as a figure file."""
    from contactvisco import api
    from contactvisco.post.figures import relaxation_figure
    try:
        scene = api.load_scene(args.scene, sets=args.set)
        fig = relaxation_figure(scene, args.temperature)
    except SceneError as err:
        print(f"contactvisco: scene error: {err}", file=sys.stderr)
        return 2
    try:
        fig.savefig(args.out, dpi=200)
    except (OSError, ValueError) as err:
        print(f"contactvisco: cannot write {args.out}: {err}", file=sys.stderr)
        return 2
    print(args.out)
    return 0


def _fit(args) -> int:
    """`contactvisco fit`: the estimates with their standard errors, one line each."""
    from contactvisco import api
    from contactvisco.io import parallel
    try:
        report = api.fit(args.description, out=args.out, progress=True)
    except SceneError as err:
        if parallel.first_rank():
            print(f"contactvisco: fit error: {err}", file=sys.stderr)
        return 2
    status = 0 if report["success"] else 3
    if not parallel.first_rank():        # every rank fits; the first one reports
        return status
    for p in report["parameters"]:
        print(f"{p['key']} = {p['estimate']:.8g} +- {p['standard_error']:.3g}"
              + ("" if p["identifiable"] else "  (not identifiable)"))
    for d in report["reduction"]["dropped"]:
        print(f"dropped {d['key']} (tau = {d['tau']:.6g}, round {d['round']}): {d['why']}")
    for warning in report["warnings"]:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"cost {report['cost']:.6g}, {report['evaluations']} forward runs, "
          f"{report['wall_s']:.1f} s: {report['message']} ({args.out})")
    return status


def _plot(args):
    import pathlib

    from contactvisco.io import files
    folder = args.folder
    if files.what(pathlib.Path(folder) / "summary.json") is None:
        print(f"contactvisco: {folder} has no summary.json: not a contactvisco output folder",
              file=sys.stderr)
        return 2
    if args.dpi <= 0:
        print(f"contactvisco: --dpi must be a positive integer, got {args.dpi}", file=sys.stderr)
        return 2
    import zipfile
    from contactvisco.post.figures import draw_all
    try:
        notes = []
        paths = draw_all(folder, fmt=args.format, dpi=args.dpi, times=args.times,
                         edges=args.edges, notes=notes)
    except SceneError as err:         # a damaged file, a link or a FIFO: named in err
        from contactvisco.io.output import DamagedFile
        what = "its files are damaged or incomplete: " if isinstance(err, DamagedFile) else ""
        print(f"contactvisco: cannot draw the figures of {folder}: {what}{err}",
              file=sys.stderr)
        return 2
    except (ValueError, KeyError, IndexError, OSError, EOFError, TypeError, RecursionError,
            zipfile.BadZipFile) as err:          # damaged or cut files
        print(f"contactvisco: cannot draw the figures of {folder}: its files are damaged or "
              f"incomplete ({type(err).__name__}: {err})", file=sys.stderr)
        return 2
    for note in notes:
        print(f"contactvisco: {note}")
    for path in paths:
        print(path)
    return 0


def _tradeoff(args):
    from contactvisco.scene import loader as scene_module
    from contactvisco.studies import tradeoff
    try:
        degrees = tuple(int(p) for p in args.degrees.split(","))
        if not degrees or min(degrees) < 1 or max(degrees) > 2:
            raise ValueError
    except ValueError:
        print(f"contactvisco: --degrees must be a comma list of 1 and 2, got '{args.degrees}'",
              file=sys.stderr)
        return 2
    try:
        name = scene_module.load(args.scene, args.set)["name"]
        out = args.out or f"results/tradeoff-{name}"
        _check_writable(out)
        result = tradeoff.tradeoff(args.scene, args.target, args.set, measure=args.measure,
                                   levels=args.levels, coarsest=args.coarsest, degrees=degrees,
                                   budget=args.budget, out=out)
    except (SceneError, tradeoff.TradeoffError) as err:
        print(f"contactvisco: tradeoff: {err}", file=sys.stderr)
        return 2
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        print("\n".join(tradeoff.summary_lines(result)))
        print(f"written: {out}/tradeoff.json, {out}/tradeoff.png"
              + (f", {out}/recommended.toml" if result["recommended"] else ""))
    return 0 if result["recommended"] else 4


if __name__ == "__main__":
    sys.exit(main())
