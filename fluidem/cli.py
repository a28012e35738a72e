"""Command line: ``fluidem bench NAME``, ``fluidem cases``.  ``python -m fluidem`` is the same."""

from __future__ import annotations

import argparse
import sys
import time

__all__ = ["main"]

#: the options each case accepts from the command line
_CASE_OPTIONS = {
    "dfg-2d1": ("element", "level"),
    "dfg-2d2": ("element", "level", "dt", "t_end", "convection"),
    "dfg-2d3": ("element", "level", "dt", "convection"),
    "square-cylinder": ("element", "level", "dt", "t_end", "convection"),
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


def _build_parser() -> argparse.ArgumentParser:
    from .cases import CASES
    from .fluid.elements import ELEMENT_PAIRS

    p = argparse.ArgumentParser(prog="fluidem", description="Resolved particle-laden flow: FEM fluid + polygonal DEM.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    b = sub.add_parser("bench", help="run a built-in benchmark case and compare with published values",
                       description="Run a benchmark case; print its quantities, the reference values, relative "
                                   "errors, DOFs and the wall-time split. Defaults are each case's own.")
    b.add_argument("name", choices=sorted(CASES), help="benchmark case")
    b.add_argument("--element", choices=sorted(ELEMENT_PAIRS), help="velocity/pressure element pair")
    b.add_argument("--level", type=int, help="mesh level (each level halves the cell size), 0-6")
    b.add_argument("--dt", type=_positive_float, help="time step (unsteady cases)")
    b.add_argument("--t-end", type=_positive_float, dest="t_end", help="end time (periodic cases)")
    b.add_argument("--convection", choices=["semi-implicit", "newton", "explicit"],
                   help="convection in time stepping: linearised with an extrapolated convecting velocity "
                        "(one linear solve per step), Newton, or explicit (one LU per run, CFL-bounded)")
    b.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    b.add_argument("--quiet", action="store_true", help="no progress output")

    sub.add_parser("cases", help="list the built-in cases", description="List the built-in benchmark cases.")
    return p


def main(argv=None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    if args.command == "cases":
        from .cases import CASES

        for name, fn in sorted(CASES.items()):
            print(f"{name:16s} {(fn.__doc__ or '').strip().splitlines()[0]}")
        return 0
    if args.command == "bench":
        from .cases import get_case

        fn = get_case(args.name)
        kwargs = {}
        for opt in ("element", "level", "dt", "t_end", "convection"):
            val = getattr(args, opt)
            if val is None:
                continue
            if opt not in _CASE_OPTIONS[args.name]:
                parser.error(f"--{opt.replace('_', '-')} does not apply to {args.name}")
            kwargs[opt] = val
        if args.name != "dfg-2d1" and not args.quiet:
            kwargs["progress"] = _Progress()
        try:
            result = fn(**kwargs)
        except ValueError as exc:
            print(f"fluidem: error: {exc}", file=sys.stderr)
            return 2
        print(result)
        if args.json:
            print(result.to_json())
        return 0
    return 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
