"""What two parts of a re-triangulation's set-up cost: the velocity block's pattern and the fluid–body system.

At every re-triangulation of a run with free bodies the flow problem is built on the new mesh, among it the CSR
pattern of the velocity block and its scatter maps (:class:`fluidem.fluid.assembly.VectorAssembler`), and the
coupled fluid–body matrix's structure with the maps that refill it (:class:`RigidBodySystem`).  At 1 000
settling polygons (1.57M DOFs) a re-triangulation step takes ~110 s, ~55 s of it in such set-up (py-spy of a
run under load: the pattern ~10 s, the fluid–body system ~24 s).  The fluid–body system's build is the same
code in the versions compared so far: its ratio shows how much the load moved between them.

Case: the settling suspension of ``bench_dense.py`` after its first step (N = 100 → 149k DOFs, 300 → ~450k);
both built again ``REPEATS`` times in one process (the velocity assembler as a whole: its pattern and its
element geometry), the medians; a SHA-1 of their arrays (the structures and
maps) to compare versions bit for bit.  With ``--before PATH`` the same with the fluidem package found at
``PATH`` (an earlier checkout), each version in its own process, the two alternating ``ROUNDS`` times; the
median over the processes.  One BLAS thread.

Run (about ten minutes)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_rebuild_setup.py [--bodies 100,300] [--before PATH]

writes ``benchmarks/results/rebuild_setup.{md,json}``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import write_results  # noqa: E402

REPEATS = 5
ROUNDS = 3


def _sha(arrays) -> str:
    sha = hashlib.sha1()
    for a in arrays:
        sha.update(np.ascontiguousarray(a).tobytes())
    return sha.hexdigest()


def _same(a: dict, b: dict) -> bool:
    return (a["pattern_sha1"], a["system_sha1"]) == (b["pattern_sha1"], b["system_sha1"])


def case(n: int) -> dict:
    """Seconds to build the velocity block's pattern and the coupled system of ``n`` settling bodies (medians of
    ``REPEATS``) and their arrays' hashes."""
    import gc
    import warnings

    import bench_dense
    from fluidem.coupling.rigid_system import RigidBodySystem
    from fluidem.fluid.assembly import VectorAssembler
    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    warnings.simplefilter("ignore")
    sim = Simulation(Scene.from_dict(bench_dense.scene_dict(n, 1)))
    sim.run(out_dir=None, n_steps=1)
    rs = next(o for o in gc.get_objects() if isinstance(o, RigidBodySystem))
    t_system, t_pattern = [], []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        va = VectorAssembler(rs.problem.space.ub)
        t_pattern.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        built = RigidBodySystem(rs.problem, rs.rigid, rs.bodies)
        t_system.append(time.perf_counter() - t0)
    return {"bodies": n, "unknowns": int(built.shape[0]), "entries": int(built._nnz),
            "pattern_s": float(np.median(t_pattern)), "system_s": float(np.median(t_system)),
            "pattern_sha1": _sha([va.indptr, va.indices, va._scatter, va._gather.indptr, va._gather.indices,
                                  *va._block_pos.values()]),
            "system_sha1": _sha([built._indptr, built._indices, built._diag_pos, *built._direct_uu,
                                 *built._direct_B, built._rest_scatter, built._rest_src_uu, built._rest_src_B,
                                 built._wr, built._wc])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bodies", default="100,300")
    ap.add_argument("--before", default=None)
    ap.add_argument("--case", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        print(json.dumps(case(args.case)))
        return
    versions = ([("before", args.before)] if args.before else []) + [("this version", None)]
    rows = []
    for n in (int(s) for s in args.bodies.split(",")):
        runs = {v: [] for v, _ in versions}
        for _ in range(ROUNDS if args.before else 1):
            for version, where in versions:
                env = dict(os.environ, **({"PYTHONPATH": where} if where else {}))
                out = subprocess.run([sys.executable, __file__, "--case", str(n)], capture_output=True, text=True,
                                     check=True, env=env)
                runs[version].append(json.loads(out.stdout.strip().splitlines()[-1]))
                print(version, runs[version][-1], flush=True)
        for version, rs in runs.items():
            rows.append(dict(rs[0], version=version, pattern_s=float(np.median([r["pattern_s"] for r in rs])),
                             system_s=float(np.median([r["system_s"] for r in rs]))))
    notes = []
    if args.before:
        pairs = [(b, t) for b in rows if b["version"] == "before" for t in rows
                 if t["version"] == "this version" and t["bodies"] == b["bodies"]]
        notes = ["", "This version against before (time ratio): " + "; ".join(
            f"{t['bodies']} bodies: assembler {t['pattern_s'] / b['pattern_s']:.2f}, system "
            f"{t['system_s'] / b['system_s']:.2f}; the arrays "
            f"{'the same bit for bit' if _same(b, t) else '**different**'}"
            for b, t in pairs) + "."]
    write_results("rebuild_setup", rows, "Two parts of a re-triangulation's set-up: the velocity assembler and the "
                  "fluid–body system",
                  f"One BLAS thread. The settling suspension of `bench_dense.py` after its first step; each built "
                  f"again {REPEATS} times in a process, the median; each version in its own process, the versions "
                  f"alternating, the median over {ROUNDS} processes a version.",
                  ["bodies", "version", "unknowns", "entries", "velocity assembler, s", "fluid–body system, s"],
                  [[str(r["bodies"]), r["version"], f"{r['unknowns']:,}", f"{r['entries']:,}",
                    f"{r['pattern_s']:.3f}", f"{r['system_s']:.2f}"] for r in rows], notes)


if __name__ == "__main__":
    sys.exit(main())
