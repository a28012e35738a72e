"""DFG flow around a cylinder (Schäfer & Turek 1996) in NGSolve: the peer of the fluidem DFG benchmarks.

Run with the python of an environment that has ``ngsolve`` (see ``benchmarks/peer_ngsolve.py``)::

    python ngsolve_dfg.py '{"case": "dfg-2d2", "order": 3, "maxh": 0.04, "maxh_cyl": 0.01, "dt": 0.000833}' out.json

Schemes, as in NGSolve's own Navier–Stokes tutorials (i-tutorials unit 3.2 / 3.3):

* ``dfg-2d1``: steady Navier–Stokes by Newton's method (``ngsolve.solvers.Newton``), started from the
  Stokes solution; Taylor–Hood P_k/P_{k-1} (k = ``order``) on a mesh curved to order k.
* ``dfg-2d2``, ``dfg-2d3``: second-order IMEX: BDF2 for the Stokes part (implicit) with the convection
  (u*·∇)u* at the extrapolated velocity u* = 2 uⁿ − uⁿ⁻¹ (explicit), i.e. per step

      M (3 uⁿ⁺¹ − 4 uⁿ + uⁿ⁻¹) / (2 Δt) + A (uⁿ⁺¹, pⁿ⁺¹) = −N(u*),

  with one factorisation of M + (2Δt/3) A for the whole run by ``sparsecholesky`` (LDLᵀ; the saddle
  point made quasi-definite by −1e-10 ∫ p q).  2D-2 starts from the Stokes solution with the brief
  cylinder rotation of fluidem's ``dfg_2d2`` (ω = 4 sin(π t / 0.5) rad/s for t < 0.5 s; ``"kick": [0, 0]``
  turns it off), which starts the shedding early and the same way on every mesh: without it the
  onset depends on the mesh's asymmetry and c_L,max was still 6.6 % low at t = 4–6 s on an 11k-DOF
  mesh.  2D-3 starts from rest.

Forces by the volume-integral (residual) method: c_D = −2 / (Ū² D) R(u, p; φ e_x) with the scheme's own
momentum residual R and a smooth cutoff φ (φ = 1 for |x − c| ≤ 0.06, C¹ decay to 0 at 0.15) interpolated
into the velocity space, its cylinder DOFs then set to e_x exactly (NGSolve's Set averages element-wise
projections, which moved c_D by 1.6e-3 on the P3/P2 maxh 0.02 mesh), so the test function equals e_x on the
cylinder and vanishes on the other boundaries; the result is then independent of the extension.
Δp = p(0.15, 0.2) − p(0.25, 0.2) (both are mesh vertices: the circle's spline points).

Output: a JSON object with the settings, DOFs, timings (perf_counter, s; ``cpu_seconds`` by
process_time, which a loaded machine does not inflate) and either the steady
quantities (cd, cl, dp) or the series t, cd, cl (normalised with Ū = 1) and dp_end.
"""

import json
import sys
import time

T_START = time.perf_counter()
CPU_START = time.process_time()

import ngsolve as ngs  # noqa: E402
from netgen.geom2d import SplineGeometry  # noqa: E402
from ngsolve import (CoefficientFunction, GridFunction, H1, IfPos, InnerProduct, Mesh, VectorH1, div, dx,  # noqa: E402
                     grad, sqrt, x, y)

T_IMPORT = time.perf_counter() - T_START
CPU_IMPORT = time.process_time() - CPU_START
H, L, D, NU, CX, CY = 0.41, 2.2, 0.1, 1e-3, 0.2, 0.2


def build_mesh(maxh, maxh_cyl, order):
    geo = SplineGeometry()
    geo.AddRectangle((0, 0), (L, H), bcs=("wall", "outlet", "wall", "inlet"))
    geo.AddCircle((CX, CY), r=D / 2, leftdomain=0, rightdomain=1, bc="cyl", maxh=maxh_cyl)
    mesh = Mesh(geo.GenerateMesh(maxh=maxh))
    mesh.Curve(order)
    return mesh


def spaces(mesh, order):
    V = VectorH1(mesh, order=order, dirichlet="wall|cyl|inlet")
    Q = H1(mesh, order=order - 1)
    X = V * Q
    return X


def force_tests(X):
    """Discrete test functions φ e_x and φ e_y (velocity component), zero pressure."""
    r = sqrt((x - CX) ** 2 + (y - CY) ** 2)
    s = IfPos(r - 0.06, IfPos(r - 0.15, 1.0, (r - 0.06) / 0.09), 0.0)
    phi = 1 - s * s * (3 - 2 * s)
    mesh = X.mesh
    on_cyl = X.GetDofs(mesh.Boundaries("cyl"))
    tests = []
    for e in ((1, 0), (0, 1)):
        g, gb = GridFunction(X), GridFunction(X)
        g.components[0].Set(CoefficientFunction((phi * e[0], phi * e[1])))
        # Set projects element by element and averages, so the cylinder DOFs are set exactly to e afterwards
        gb.components[0].Set(CoefficientFunction(e), definedon=mesh.Boundaries("cyl"))
        for i in range(len(on_cyl)):
            if on_cyl[i]:
                g.vec[i] = gb.vec[i]
        tests.append(g)
    return tests


def inflow(U):
    return CoefficientFunction((4 * U * y * (H - y) / H**2, 0))


def stokes_form(u, v, p, q):
    """ν ∇u:∇v − p div v − q div u − 1e-10 p q (physical pressure sign)."""
    return NU * InnerProduct(grad(u), grad(v)) - div(u) * q - div(v) * p - 1e-10 * p * q


def dp_of(mesh, gfu):
    gp = gfu.components[1]
    return gp(mesh(0.15, 0.2)) - gp(mesh(0.25, 0.2))


def steady(cfg):
    t0 = time.perf_counter()
    mesh = build_mesh(cfg["maxh"], cfg.get("maxh_cyl") or cfg["maxh"], cfg["order"])
    t_mesh = time.perf_counter() - t0
    X = spaces(mesh, cfg["order"])
    (u, p), (v, q) = X.TnT()
    gfu = GridFunction(X)
    gfu.components[0].Set(inflow(0.3), definedon=mesh.Boundaries("inlet"))
    a = ngs.BilinearForm(X)
    a += (stokes_form(u, v, p, q) + InnerProduct(grad(u) * u, v)) * dx
    st = ngs.BilinearForm(X, symmetric=True)
    st += stokes_form(u, v, p, q) * dx
    st.Assemble()
    res = gfu.vec.CreateVector()
    res.data = -st.mat * gfu.vec
    gfu.vec.data += st.mat.Inverse(X.FreeDofs(), inverse="sparsecholesky") * res
    t_asm = time.perf_counter() - t0 - t_mesh
    tol = cfg.get("newton_tol", 1e-11)
    its = ngs.solvers.Newton(a, gfu, freedofs=X.FreeDofs(), maxit=20, maxerr=tol, inverse=cfg.get("inverse", "umfpack"),
                             printing=False)
    t_solve = time.perf_counter() - t0 - t_mesh - t_asm
    a.Apply(gfu.vec, res)
    tx, ty = force_tests(X)
    scale = -2.0 / (0.2**2 * D)
    out = {"cd": scale * InnerProduct(res, tx.vec), "cl": scale * InnerProduct(res, ty.vec), "dp": dp_of(mesh, gfu),
           "newton_iterations": its[1] if isinstance(its, tuple) else its}
    return mesh, X, out, {"mesh": t_mesh, "assembly": t_asm, "solve": t_solve}


def unsteady(cfg):
    case = cfg["case"]
    dt, t_end = cfg["dt"], cfg.get("t_end", 6.0 if case == "dfg-2d2" else 8.0)
    import math
    U = (lambda t: 1.5) if case == "dfg-2d2" else (lambda t: 1.5 * math.sin(math.pi * t / 8.0))
    t_kick, om_kick = cfg.get("kick", (0.5, 4.0) if case == "dfg-2d2" else (0.0, 0.0))

    def omega(t):                               # the brief cylinder rotation that starts the shedding
        return om_kick * math.sin(math.pi * t / t_kick) if t < t_kick else 0.0
    t0 = time.perf_counter()
    mesh = build_mesh(cfg["maxh"], cfg.get("maxh_cyl") or cfg["maxh"], cfg["order"])
    t_mesh = time.perf_counter() - t0
    X = spaces(mesh, cfg["order"])
    (u, p), (v, q) = X.TnT()
    c = 2.0 * dt / 3.0
    m = ngs.BilinearForm(X, symmetric=True)
    m += InnerProduct(u, v) * dx
    a = ngs.BilinearForm(X, symmetric=True)
    a += stokes_form(u, v, p, q) * dx
    mstar = ngs.BilinearForm(X, symmetric=True)
    mstar += (InnerProduct(u, v) + c * stokes_form(u, v, p, q)) * dx
    conv = ngs.BilinearForm(X, nonassemble=True)
    conv += InnerProduct(grad(u) * u, v) * dx
    for f in (m, a, mstar):
        f.Assemble()
    gin = GridFunction(X)                       # inflow profile for U = 1 on the inlet DOFs only
    gin.components[0].Set(inflow(1.0), definedon=mesh.Boundaries("inlet"))
    grot = GridFunction(X)                      # rigid rotation with ω = 1 rad/s on the cylinder DOFs only
    grot.components[0].Set(CoefficientFunction((-(y - CY), x - CX)), definedon=mesh.Boundaries("cyl"))
    t_asm = time.perf_counter() - t0 - t_mesh
    inv = mstar.mat.Inverse(X.FreeDofs(), inverse="sparsecholesky")
    t_fact = time.perf_counter() - t0 - t_mesh - t_asm

    un = GridFunction(X)
    un.vec.data = U(0.0) * gin.vec
    if case == "dfg-2d2":                       # Stokes solution as the start
        r = un.vec.CreateVector()
        r.data = -a.mat * un.vec
        un.vec.data += a.mat.Inverse(X.FreeDofs(), inverse="sparsecholesky") * r
    unm1 = un.vec.CreateVector()
    unm1.data = un.vec
    tx, ty = force_tests(X)
    tmx, tmy = un.vec.CreateVector(), un.vec.CreateVector()
    tax, tay = un.vec.CreateVector(), un.vec.CreateVector()
    tmx.data, tmy.data = m.mat * tx.vec, m.mat * ty.vec
    tax.data, tay.data = a.mat * tx.vec, a.mat * ty.vec
    ustar, nvec, w, tmp, rhs = (un.vec.CreateVector() for _ in range(5))
    n = int(round(t_end / dt))
    ts, cds, cls_ = [], [], []
    diverged = None
    t_prep = time.perf_counter() - t0 - t_mesh - t_asm - t_fact
    t_loop0 = time.perf_counter()
    for k in range(n):
        t_old, t_new = k * dt, (k + 1) * dt
        ustar.data = 2.0 * un.vec - unm1
        conv.Apply(ustar, nvec)
        w.data = un.vec + (U(t_new) - U(t_old)) * gin.vec      # Dirichlet values of t_new, uⁿ elsewhere
        if t_old < t_kick:
            w.data += (omega(t_new) - omega(t_old)) * grot.vec
        tmp.data = w - (4.0 / 3.0) * un.vec + (1.0 / 3.0) * unm1
        rhs.data = m.mat * tmp
        tmp.data = a.mat * w
        rhs.data += c * tmp
        rhs.data += c * nvec
        rhs.data *= -1.0
        w.data += inv * rhs
        # momentum residual of the step against φ e_x, φ e_y (M, A symmetric)
        tmp.data = (1.5 / dt) * w - (2.0 / dt) * un.vec + (0.5 / dt) * unm1
        fx = InnerProduct(tmx, tmp) + InnerProduct(tax, w) + InnerProduct(tx.vec, nvec)
        fy = InnerProduct(tmy, tmp) + InnerProduct(tay, w) + InnerProduct(ty.vec, nvec)
        unm1.data = un.vec
        un.vec.data = w
        ts.append(t_new)
        cds.append(-2.0 / D * fx)
        cls_.append(-2.0 / D * fy)
        if not abs(cds[-1]) < 1e3:
            diverged = t_new
            break
    t_loop = time.perf_counter() - t_loop0
    out = {"t": ts, "cd": cds, "cl": cls_, "dp_end": dp_of(mesh, un) if diverged is None else None,
           "steps": len(ts), "diverged_at": diverged, "ms_per_step": 1e3 * t_loop / max(len(ts), 1)}
    return mesh, X, out, {"mesh": t_mesh, "assembly": t_asm + t_prep, "factorisation": t_fact, "steps": t_loop}


def main():
    cfg = json.loads(sys.argv[1])
    ngs.ngsglobals.msg_level = 0
    run = steady if cfg["case"] == "dfg-2d1" else unsteady
    mesh, X, out, timings = run(cfg)
    out.update({"config": cfg, "dofs": X.ndof, "free_dofs": sum(X.FreeDofs()), "elements": mesh.ne,
                "timings": timings, "ngsolve_version": ngs.__version__, "import_seconds": T_IMPORT,
                "wall_seconds": time.perf_counter() - T_START - T_IMPORT,
                "cpu_seconds": time.process_time() - CPU_START - CPU_IMPORT})
    text = json.dumps(out)
    if len(sys.argv) > 2:
        with open(sys.argv[2], "w") as fh:
            fh.write(text)
    else:
        print(text)


if __name__ == "__main__":
    main()
