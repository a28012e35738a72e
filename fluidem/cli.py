"""Command line: ``fluidem bench NAME``, ``fluidem cases``.  ``python -m fluidem`` is the same.

Scenes: ``fluidem run SCENE``, ``fluidem plan SCENE``, ``fluidem examples [--show NAME]``,
``fluidem new NAME DIR``, ``fluidem reference``, ``fluidem plot DIR``; random bodies for a scene's
CSV body table: ``fluidem fill OUT.csv --box ... --fraction PHI`` (:mod:`fluidem.scene.fill`); parameter sweeps:
``fluidem sweep SCENE --vary KEY=V1,V2 [--vary ...]`` (:mod:`fluidem.sweep`).

Every name an option takes (cases, element pairs, convection schemes, solvers, example
scenes) comes from :mod:`fluidem.names`, the table scene files and the Python factories
read too; old spellings are accepted as aliases.  An error fluidem raises on purpose
(:class:`fluidem.errors.FluidemError`, or a ``ValueError`` from validation) prints one line
``fluidem: error: <message>`` to stderr and exits with status 2; ``--debug`` shows the
traceback instead.  A run stopped by Ctrl-C or SIGTERM exits with 130 or 143, a run whose
step failed with 3, each after a one-line message saying where its last checkpoint is and
how to continue (``fluidem run SCENE --out DIR --restart``; without ``SCENE`` a restart continues the
``scene.toml`` the run wrote in ``DIR``).  ``fluidem plan`` exits with 2
for a scene this version cannot run (the plan's ``unsupported`` reasons, one
``fluidem: error:`` line each on stderr, after the plan on stdout), and ``fluidem run``
refuses such a scene with the same lines before building anything.  ``--overwrite`` clears an
earlier run's output in the directory (a fresh run into it is refused otherwise).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

from . import names
from .errors import FluidemError

__all__ = ["main"]

#: the options each case accepts from the command line
_CASE_OPTIONS = {
    "dfg-2d1": ("element", "level", "solver"),
    "dfg-2d2": ("element", "level", "dt", "t_end", "convection", "solver", "scheme"),
    "dfg-2d3": ("element", "level", "dt", "convection", "solver", "scheme"),
    "square-cylinder": ("element", "level", "dt", "t_end", "convection", "solver"),
    "settling-disk": ("element", "dt", "t_end"),
    "dkt": ("element", "dt", "t_end"),
}


class _Progress:
    """Prints steps, simulated time, elapsed time and ETA to stderr."""

    def __init__(self):
        self.t0 = time.perf_counter()

    def __call__(self, k, n, t):
        el = time.perf_counter() - self.t0
        eta = el / k * (n - k)
        print(f"  step {k}/{n}  t = {t:.4g}  elapsed {el:.0f} s  ETA {eta:.0f} s", file=sys.stderr, flush=True)


def _positive_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def _positive_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def _nonnegative_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return v


def _name(kind: str):
    """An argparse ``type`` that turns a registry name or alias of ``kind`` into its canonical name.

    Unknown values pass through unchanged, so that argparse's ``choices`` check reports them.
    """
    def convert(text):
        try:
            return names.lookup(kind, text)
        except ValueError:
            return text

    convert.__name__ = kind  # argparse names the type in its messages
    return convert


def _named(kind: str) -> dict:
    """``type=`` and ``choices=`` of an option taking a name of ``kind`` from :mod:`fluidem.names`."""
    return {"type": _name(kind), "choices": names.choices(kind)}


def _add_debug(parser, default=False) -> None:
    parser.add_argument("--debug", action="store_true", default=default,
                        help="on an error, show the traceback instead of one line")


def _build_parser() -> argparse.ArgumentParser:
    from .version import __version__

    p = argparse.ArgumentParser(prog="fluidem", description="Resolved particle-laden flow: FEM fluid + polygonal DEM.")
    p.add_argument("--version", action="version", version=f"fluidem {__version__}")
    _add_debug(p)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    b = sub.add_parser("bench", help="run a built-in benchmark case and compare with published values",
                       description="Run a benchmark case; print its quantities, the reference values, relative "
                                   "errors, DOFs and the wall-time split. Defaults are each case's own.")
    b.add_argument("name", help="benchmark case", **_named("case"))
    b.add_argument("--element", help="velocity/pressure element pair", **_named("element"))
    b.add_argument("--level", type=_nonnegative_int, help="mesh level (each level halves the cell size), 0-6")
    b.add_argument("--dt", type=_positive_float, help="time step (unsteady cases)")
    b.add_argument("--t-end", type=_positive_float, dest="t_end", help="end time (periodic cases)")
    b.add_argument("--convection", **_named("convection"),
                   help="convection in time stepping: linearised with an extrapolated convecting velocity "
                        "(one linear solve per step), Newton, or explicit (one LU per run, CFL-bounded)")
    b.add_argument("--scheme", **_named("time scheme"),
                   help="BDF formula of the unsteady cases: bdf2, bdf3 (auto: the case's default, BDF3)")
    b.add_argument("--solver", **_named("solver"),
                   help="linear solver: LU, block-preconditioned GMRES, an LU reused as GMRES "
                        "preconditioner across steps, or auto (by size); default: auto for steady, "
                        "lagged for unsteady cases")
    b.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    b.add_argument("--quiet", action="store_true", help="no progress output")

    sub.add_parser("cases", help="list the built-in cases", description="List the built-in benchmark cases.")
    _add_scene_commands(sub)
    _add_fill_command(sub)
    _add_sweep_command(sub)
    for command in sub.choices.values():  # --debug after the command too; absent there, the top level's counts
        _add_debug(command, default=argparse.SUPPRESS)
    return p


def _add_scene_commands(sub) -> None:
    """``run``, ``plan``, ``examples``, ``new``, ``reference`` and ``plot``: the scene path."""
    r = sub.add_parser("run", help="run a scene file (or a built-in example) and write its output",
                       description="Run a scene: history.csv, fields and body outlines (VTU + PVD), mesh "
                                   "quality, events.log, checkpoints and run.json in the output directory. "
                                   "A directory holding another run's output is refused unless --overwrite or "
                                   "--restart. Ctrl-C or SIGTERM stops after the step in progress with a checkpoint.")
    r.add_argument("scene", nargs="?", help="scene TOML file")
    r.add_argument("--example", metavar="NAME", help="a built-in scene instead of a file: "
                   + ", ".join(names.choices("example")) + " (see 'fluidem examples')")
    r.add_argument("--out", metavar="DIR", help="output directory (default: the scene's [output] dir)")
    r.add_argument("--restart", nargs="?", const=True, metavar="CHECKPOINT",
                   help="continue from a checkpoint file, or from the newest valid one in the output directory "
                        "(only time.t_end and [output] may differ from the run's scene; with no scene given, "
                        "the scene.toml the run wrote in its output directory)")
    r.add_argument("--overwrite", action="store_true",
                   help="clear the output of an earlier run in the output directory first")
    r.add_argument("--steps", type=_positive_int, metavar="N", help="stop after N steps in total (N >= 1)")
    r.add_argument("--plot", action="store_true", help="draw the PNG figures at the end")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("-v", "--verbose", action="store_true",
                   help="one line per step instead of the bar: linear solver iterations and residual, CFL number "
                        "and the step's cost split")
    pl = sub.add_parser("plan", help="print the effects a scene needs and why",
                        description="Validate a scene and print its plan: which effects are on, and why. "
                                    "Exits with status 2, one error line per reason, for a scene this version "
                                    "cannot run.")
    pl.add_argument("scene", nargs="?", help="scene TOML file")
    pl.add_argument("--example", metavar="NAME", help="a built-in scene instead of a file: "
                    + ", ".join(names.choices("example")))
    ex = sub.add_parser("examples", help="list the built-in example scenes, or print one to copy",
                        description="List the built-in example scenes ('fluidem run --example NAME'); --show "
                                    "NAME prints one as TOML to start a scene of your own from.")
    ex.add_argument("--show", metavar="NAME", help="print the scene file of example NAME (its CSV body table, "
                    "if any, is named in a comment at the top)")
    nw = sub.add_parser("new", help="copy a built-in example scene (and its CSV body table) into a directory",
                        description="Copy the scene file of example NAME, and its CSV body table if it has one, "
                                    "into DIR (created if missing; existing files are not overwritten).")
    nw.add_argument("name", metavar="NAME", help="example scene: " + ", ".join(names.choices("example")))
    nw.add_argument("dir", metavar="DIR", help="directory to copy it into")
    sub.add_parser("reference", help="print the scene file reference (Markdown)",
                   description="Print every table and key a scene file takes, with type, default, unit and "
                               "allowed values (the text of docs/scenes.md).")
    pt = sub.add_parser("plot", help="draw PNG figures of a run directory",
                        description="Mesh, velocity magnitude with streamlines, pressure, bodies, body "
                                    "trajectories and the history over time (loads, velocities, energy, mesh "
                                    "quality), as PNG files in DIR/plots (or --to). Needs matplotlib: pip install "
                                    "\"fluidem[plot]\".")
    pt.add_argument("dir", help="output directory of 'fluidem run'")
    pt.add_argument("--to", metavar="DIR", help="where to write the PNG files")
    pt.add_argument("--units", **_named("units"), help="name the units in the labels (the scene must be in "
                    "that system; nothing is converted); default: the scene's units, else dimensions, e.g. "
                    "[length]")


def _add_fill_command(sub) -> None:
    from .scene.fill import DEFAULT_ATTEMPTS, SHAPES

    fl = sub.add_parser("fill", help="write a CSV body table of random non-overlapping bodies (a suspension)",
                        description="Fill a box with random non-overlapping bodies by random sequential addition "
                                    "and write them as the CSV body table of a scene ([bodies_table] file = OUT). "
                                    "Give --n or --fraction; sizes are equal-area radii (a body of radius r has "
                                    "the area pi r^2 whatever its shape). Random sequential addition jams near "
                                    "area fraction 0.5 (docs/suspensions.md).")
    fl.add_argument("out", metavar="OUT.csv", help="CSV file to write (refused if it exists, unless --overwrite)")
    fl.add_argument("--box", type=float, nargs=4, required=True, metavar=("XMIN", "XMAX", "YMIN", "YMAX"),
                    help="the region to fill (a scene's domain.box or part of it)")
    fl.add_argument("--n", type=int, metavar="N", help="number of bodies")
    fl.add_argument("--fraction", type=float, metavar="PHI", help="area fraction of the box the bodies cover, in "
                    "(0, 1); with --n and no --radius: N equal bodies of the radius that covers it")
    fl.add_argument("--radius", type=float, nargs="+", metavar="R", help="equal-area radius, or a range R_MIN "
                    "R_MAX drawn uniformly")
    fl.add_argument("--shapes", default="disk", metavar="NAME[:W],...",
                    help="shapes drawn, comma-separated, each with an optional relative weight: "
                         + ", ".join(SHAPES) + " or N-gon (e.g. disk:2,hexagon,7-gon); default disk")
    fl.add_argument("--aspect", type=float, default=2.0, help="width / height of the rectangles (default 2)")
    fl.add_argument("--density", type=float, metavar="RHO", help="areal density of every body (a density column; "
                    "default: none, the scene's [bodies_table] density applies)")
    fl.add_argument("--seed", type=int, default=0, help="random seed (default 0): the same options give the same "
                    "bodies")
    fl.add_argument("--min-gap", type=float, dest="min_gap", metavar="G",
                    help="smallest distance between outlines (default 0.1 x the mean radius)")
    fl.add_argument("--side-gap", type=float, dest="side_gap", metavar="G",
                    help="smallest distance from an outline to a side of the box (default: --min-gap)")
    fl.add_argument("--periodic", default="", metavar="AXES", help="periodic axes of the box: x, y or xy (bodies "
                    "are placed across those sides too, gaps measured to the nearest image; a fluid scene meshes "
                    "them on the moving mesh)")
    fl.add_argument("--segments", type=int, metavar="N", help="outline vertices of the disks (default: the "
                    "scene's choice, a curved circle in a fluid scene)")
    fl.add_argument("--attempts", type=int, default=DEFAULT_ATTEMPTS, metavar="N",
                    help=f"candidate places tried for one body before giving up (default {DEFAULT_ATTEMPTS})")
    fl.add_argument("--overwrite", action="store_true", help="replace OUT.csv if it exists")


def _fill_main(args) -> int:
    from .errors import InputError
    from .scene.fill import fill

    out = Path(args.out)
    if out.exists() and not args.overwrite:  # before the work
        raise InputError(f"{str(out)!r} exists already; expected a new file name (or --overwrite)")
    shapes = {}
    for item in args.shapes.split(","):
        name, _, w = item.strip().partition(":")
        try:
            shapes[name] = shapes.get(name, 0.0) + (float(w) if w else 1.0)
        except ValueError:
            raise InputError(f"--shapes weight of {name!r} = {w!r}: expected a positive number (NAME:W)") from None
    labels = {"region": "--box", "n": "--n", "area_fraction": "--fraction", "shapes": "--shapes",
              "radius": "--radius", "aspect": "--aspect", "seed": "--seed", "min_gap": "--min-gap",
              "side_gap": "--side-gap", "periodic": "--periodic", "segments": "--segments", "attempts": "--attempts"}
    if args.density is not None and not args.density > 0:
        raise InputError(f"--density = {args.density!r}: expected a positive finite number")
    radius = None if args.radius is None else (args.radius[0] if len(args.radius) == 1 else args.radius)
    packing = fill(args.box, n=args.n, area_fraction=args.fraction, shapes=shapes, radius=radius, aspect=args.aspect,
                   seed=args.seed, min_gap=args.min_gap, side_gap=args.side_gap, periodic=args.periodic,
                   segments=args.segments, attempts=args.attempts, labels=labels)
    packing.to_csv(out, density=args.density, overwrite=args.overwrite)
    print(f"{out}: {packing}")
    print(f'in a scene: [bodies_table] file = "{out.name}" (next to the scene file)')
    return 0


def _add_sweep_command(sub) -> None:
    sw = sub.add_parser("sweep", help="run every combination of some scene values as tasks on dask.distributed",
                        description="Run a parameter sweep: every combination of the --vary values, each variant "
                                    "one task (one process, one BLAS thread) on a LocalCluster (one worker per core) "
                                    "or an existing scheduler. Writes DIR/<variant>/ run directories, sweep.csv, "
                                    "sweep.json and sweep.png; finished variants are not run again. Needs "
                                    "dask.distributed: pip install \"fluidem[sweep]\" (editable checkout: "
                                    "pip install -e \".[sweep]\").")
    sw.add_argument("scene", nargs="?", help="scene TOML file")
    sw.add_argument("--example", metavar="NAME", help="a built-in scene instead of a file: "
                    + ", ".join(names.choices("example")))
    sw.add_argument("--vary", action="append", required=True, metavar="KEY=V1,V2,...",
                    help="a dotted scene key and its values, e.g. mesh.h=0.04,0.02 or fluid.element=th,p3 "
                         "(repeat for more keys; values are read as TOML, bare words as strings)")
    sw.add_argument("--scheduler", metavar="ADDR", help="address of a running dask scheduler (default: a new "
                    "LocalCluster)")
    sw.add_argument("--workers", type=_positive_int, metavar="N", help="LocalCluster worker processes "
                    "(default: one per core)")
    sw.add_argument("--out", metavar="DIR", help="sweep directory (default: sweep-<scene name>)")
    sw.add_argument("--steps", type=_positive_int, metavar="N", help="stop every variant after N steps")
    sw.add_argument("--quantity", metavar="COLUMN", help="plotted column of the table, e.g. cylinder.fx "
                    "(default: the first body's fx)")
    sw.add_argument("--reference", type=float, metavar="VALUE",
                    help="plot the relative error of --quantity against this value")
    sw.add_argument("--no-plot", action="store_true", help="write no sweep.png")
    sw.add_argument("--overwrite", action="store_true", help="run every variant again, also over another scene's "
                    "sweep (or a run) in DIR, which is refused otherwise")
    sw.add_argument("--quiet", action="store_true", help="no progress lines")


def _sweep_main(args) -> int:
    from .sweep import parse_vary, require_dask, sweep

    require_dask("'fluidem sweep'")
    scene = _scene_from_args(args)
    vary = parse_vary(args.vary)
    table = sweep(scene, vary, out_dir=args.out or f"sweep-{scene.name}", scheduler=args.scheduler,
                  workers=args.workers, n_steps=args.steps, quantity=args.quantity, reference=args.reference,
                  progress=not args.quiet, plot=not args.no_plot, overwrite=args.overwrite)
    for path in table.files:
        print(path)
    return 0 if all(r["status"] == "complete" for r in table) else 3


class _ProgressBar:
    """Progress on ``stream`` (default stderr): steps, simulated time, ETA and the last step's cost split.

    On a terminal one bar is redrawn in place (``\\r``, at most five times a second); written to
    a file or a pipe (``stream.isatty()`` false) each update is a line of its own, printed at
    the first step, whenever another ``plain_fraction`` of the steps is done or ``plain_seconds``
    have passed since the last line, and at the last step.
    """

    def __init__(self, width: int = 30, stream=None, plain_fraction: float = 0.05, plain_seconds: float = 10.0):
        self.t0 = time.perf_counter()
        self.width = width
        self.stream = stream
        self.k0 = None
        self.last = 0.0
        self.plain_fraction = plain_fraction
        self.plain_seconds = plain_seconds
        self.k_last = None

    def _out(self):
        return self.stream if self.stream is not None else sys.stderr

    def __call__(self, k, n, t, cost):
        now = time.perf_counter()
        out = self._out()
        tty = bool(getattr(out, "isatty", lambda: False)())
        if self.k0 is None:
            self.k0 = k - 1
        if tty:
            if k < n and now - self.last < 0.2:
                return
        elif k < n and self.k_last is not None and k - self.k_last < self.plain_fraction * n \
                and now - self.last < self.plain_seconds:
            return
        self.last, self.k_last = now, k
        el = now - self.t0
        done = k - self.k0
        eta = el / max(done, 1) * (n - k)
        text = f"{k}/{n}  t = {t:.4g}  elapsed {el:.0f} s  ETA {eta:.0f} s  last step: {cost}"
        if not tty:
            print(f"step {text}", file=out, flush=True)
            return
        fill = int(self.width * k / max(n, 1))
        bar = "#" * fill + "." * (self.width - fill)
        print(f"\r[{bar}] {text}   ", end="\n" if k >= n else "", file=out, flush=True)


def _scene_from_args(args):
    from .errors import InputError
    from .scene import Scene

    if args.example and args.scene:
        raise InputError("give a scene file or --example NAME, not both")
    if args.example:
        from .cases.scenes import example_scene

        return example_scene(args.example)
    if not args.scene:
        own = _restarted_scene(args)
        if own is not None:
            return Scene.from_toml(own)
        raise InputError("no scene: give a scene TOML file or --example NAME (see 'fluidem examples')"
                         + (", or with --restart an --out directory holding a run's scene.toml"
                            if getattr(args, "restart", None) else ""))
    return Scene.from_toml(args.scene)


def _restarted_scene(args):
    """The scene a ``run --restart`` without a scene continues: the ``scene.toml`` its run wrote in the output
    directory (``--out``, or the run directory of a ``--restart CHECKPOINT`` file, which then becomes ``--out``),
    else None."""
    restart = getattr(args, "restart", None)
    if not restart:
        return None
    if args.out:
        out = Path(args.out)
    elif restart is not True:
        ck = Path(restart)
        out = ck if ck.is_dir() else ck.parent.parent  # OUT/checkpoints/ckpt_*.npz
    else:
        return None
    own = out / "scene.toml"
    if not own.is_file():
        return None
    args.out = str(out)
    return own


def _scene_main(args) -> int:
    if args.command == "examples":
        from .cases.scenes import example_descriptions, example_text

        if args.show:
            print(example_text(args.show), end="")
            return 0
        descriptions = example_descriptions()
        width = max(map(len, descriptions))
        for name, desc in descriptions.items():
            print(f"{name:{width}s} {desc}")
        return 0
    if args.command == "new":
        from .cases.scenes import copy_example

        for path in copy_example(args.name, args.dir):
            print(path)
        return 0
    if args.command == "reference":
        from .scene.reference import markdown

        print(markdown(), end="")
        return 0
    if args.command == "plot" or getattr(args, "plot", False):  # before anything runs
        from .plotting import require_matplotlib

        require_matplotlib("--plot" if args.command == "run" else "'fluidem plot'")
    if args.command == "plot":
        from .plotting import plot_run

        for path in plot_run(args.dir, args.to, units=args.units):
            print(path)
        return 0
    scene = _scene_from_args(args)
    plan = scene.plan()
    if args.command == "plan":
        print(plan)
        return _refuse(plan)
    if plan.unsupported:  # before anything is built: the same reasons as 'fluidem plan'
        return _refuse(plan)
    from .simulation import Simulation

    sim = Simulation(scene)
    out = args.out or scene.output.dir
    if not args.quiet:
        print(sim.plan, file=sys.stderr)
    result = sim.run(out_dir=out, restart=args.restart, n_steps=args.steps, overwrite=args.overwrite,
                     progress=None if args.quiet or args.verbose else _ProgressBar(), verbose=args.verbose)
    print(result)
    if args.plot:
        from .plotting import plot_run

        for path in plot_run(out):
            print(path)
    return 0


#: exit status when standard output is a pipe closed by its reader (128 + SIGPIPE, as the shell reports it)
BROKEN_PIPE_STATUS = 141

#: exit status of ``fluidem plan`` and ``fluidem run`` for a scene this version cannot run
CANNOT_RUN_STATUS = 2


def _refuse(plan) -> int:
    """0 when ``plan`` can run; otherwise one ``fluidem: error:`` line per reason it cannot (stderr)
    and :data:`CANNOT_RUN_STATUS`."""
    if not plan.unsupported:
        return 0
    for reason in plan.unsupported:
        print(f"fluidem: error: scene {plan.scene_name!r} cannot run: {_one_line(reason)}", file=sys.stderr)
    return CANNOT_RUN_STATUS


def _bench_main(args, parser) -> int:
    from .cases import get_case

    fn = get_case(args.name)
    kwargs = {}
    for opt in ("element", "level", "dt", "t_end", "convection", "solver", "scheme"):
        val = getattr(args, opt)
        if val is None:
            continue
        if opt not in _CASE_OPTIONS[args.name]:
            parser.error(f"--{opt.replace('_', '-')} does not apply to {args.name}")
        if opt == "scheme":
            if val != "auto":
                kwargs["order"] = int(val[-1])
            continue
        kwargs[opt] = val
    if args.name != "dfg-2d1" and not args.quiet:
        kwargs["progress"] = _Progress()
    result = fn(**kwargs)
    print(result)
    if args.json:
        print(result.to_json())
    return 0


def _dispatch(args, parser) -> int:
    if args.command == "cases":
        from .cases import get_case

        for name in names.choices("case"):
            print(f"{name:16s} {(get_case(name).__doc__ or '').strip().splitlines()[0]}")
        return 0
    if args.command in ("run", "plan", "examples", "plot", "new", "reference"):
        return _scene_main(args)
    if args.command == "bench":
        return _bench_main(args, parser)
    if args.command == "sweep":
        return _sweep_main(args)
    if args.command == "fill":
        return _fill_main(args)
    return 1


def main(argv=None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit status.

    Errors fluidem raises on purpose (:class:`~fluidem.errors.FluidemError`, and the
    ``ValueError`` of validation) and a path the system cannot read or write print
    ``fluidem: error: <message>`` on one line to stderr and return 2 (a run stopped by an
    interrupt or by a bad state returns its own status, see :mod:`fluidem.simulation`); any
    other exception prints one line too and returns 1; with ``--debug`` they propagate with
    their traceback.  Output into a pipe its reader closed (``fluidem examples | head``) stops
    quietly with :data:`BROKEN_PIPE_STATUS`.  Usage errors exit through argparse (status 2).
    """
    parser = _build_parser()
    args = parser.parse_args(argv)
    try:
        with warnings.catch_warnings():
            if not args.debug:
                warnings.showwarning = _show_warning
            status = _dispatch(args, parser)
            sys.stdout.flush()  # a closed pipe shows here, not at exit
            return status
    except BrokenPipeError:  # 'fluidem examples | head': the reader has gone; stop quietly like standard tools
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing more to flush at exit
        except (OSError, ValueError):
            pass
        return BROKEN_PIPE_STATUS
    except (FluidemError, ValueError) as exc:
        if args.debug:
            raise
        status = getattr(exc, "exit_status", 2)
        print(f"fluidem: error: {_one_line(exc)}", file=sys.stderr)
        return status
    except OSError as exc:  # a path that cannot be read or written: the system's reason and the path
        if args.debug:
            raise
        where = f": {exc.filename!r}" if getattr(exc, "filename", None) else ""
        print(f"fluidem: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if args.debug:
            raise
        print("fluidem: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # not raised on purpose: still one line, the traceback with --debug
        if args.debug:
            raise
        print(f"fluidem: error: {type(exc).__name__}: {_one_line(exc)} (an unexpected error: run again with --debug "
              "for the traceback)", file=sys.stderr)
        return 1


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """fluidem's own warnings as ``fluidem: warning: <message>`` (others as Python prints them)."""
    if category.__module__.startswith("fluidem"):
        print(f"fluidem: warning: {_one_line(message)}", file=sys.stderr)
    else:
        print(warnings.formatwarning(message, category, filename, lineno, line), end="", file=sys.stderr)


def _one_line(exc) -> str:
    return " ".join(str(exc).splitlines()) or type(exc).__name__


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
