# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # A free disk settling in a channel
#
# A disk of radius a = 0.1 and density ρ_s = 1.5 is released at rest on the centre line of
# a closed vertical channel of width 2l = 1 (k = a/l = 0.2) full of fluid (ρ_f = 1,
# ν = 0.01), under gravity g = 1 downwards. Nothing prescribes its motion: each step the
# coupled solver moves the mesh with the predicted pose and solves the fluid and the disk's
# Newton–Euler equations in one system. It speeds up until the drag balances the buoyant
# weight. We compare its speed with two references:
#
# * the terminal velocity of the same disk computed independently in its own frame
#   (`fluidem.cases.settling.steady_terminal_velocity`: steady Navier–Stokes flow past a
#   fixed disk with moving walls, drag = buoyant weight by a secant iteration);
# * in Stokes flow, Faxén's (1946) drag of a cylinder between two plane walls.
#
# A coarse mesh (h = 0.04 at the disk) and Taylor–Hood elements keep this to a few seconds.

# %%
import math
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from fluidem.cases.settling import settling_scene, steady_terminal_velocity
from fluidem.io import read_history
from fluidem.plotting import figures
from fluidem.scene import Scene
from fluidem.simulation import Simulation

a, nu, density, g = 0.1, 0.01, 1.5, 1.0
h, dt, t_end, element = 0.04, 0.025, 5.0, "th"

# %% [markdown]
# ## The reference: steady flow in the disk's frame
#
# The disk is held fixed, the walls move up at U and fluid enters uniformly at U from below;
# U is iterated until the drag equals the buoyant weight (ρ_s − ρ_f) A g. Same element and
# mesh size at the disk, different mesh generator, no time stepping, no coupling.

# %%
t0 = time.perf_counter()
ref = steady_terminal_velocity(a=a, density=density, nu=nu, g=g, h=h, element=element)
U_ref = ref["U"]
print(f"terminal velocity {U_ref:.6f} after {ref['iterations']} steady solves ({ref['dofs']} DOFs, "
      f"{time.perf_counter() - t0:.1f} s); drag {ref['drag']:.6f} = buoyant weight {ref['weight']:.6f}")
print(f"Reynolds number 2aU/ν = {2 * a * U_ref / nu:.2f}")

# %% [markdown]
# ## The free disk
#
# `settling_scene` is the lab-frame scene (a 64-gon released at (0, 4) in [−0.5, 0.5] × [0, 6]);
# we keep only the last fields and no checkpoints.

# %%
scene = settling_scene(a=a, density=density, nu=nu, g=g, h=h, dt=dt, t_end=t_end, element=element).to_dict()
scene["output"] = {"every": 10_000, "checkpoint_every": 0}
sim = Simulation(Scene.from_dict(scene))
print(sim.plan)
out = Path(tempfile.mkdtemp()) / "settling"
t0 = time.perf_counter()
sim.run(out_dir=out)
print(f"{sim.plan.n_steps} steps in {time.perf_counter() - t0:.1f} s, {sim.flow.dofs} DOFs, "
      f"{sim.counters['triangulations']} triangulations")

# %% [markdown]
# ## Velocity against the reference
#
# The approach to the terminal velocity is exponential, so the limit follows from three
# equally spaced samples by Aitken's Δ² extrapolation.

# %%
hist = read_history(out)
t, vy, x = hist["t"], -hist["vy"], hist["x"]
every = int(round(0.5 / dt))
s = vy[every - 1::every][-3:]   # the speed at t = 4, 4.5, 5
U_free = s[2] - (s[2] - s[1]) ** 2 / ((s[2] - s[1]) - (s[1] - s[0]))
print(f"speed at t = {t[-1]:.1f}: {vy[-1]:.6f} ({vy[-1] / U_ref - 1:+.2e} from the reference)")
print(f"extrapolated terminal speed {U_free:.6f}: {U_free / U_ref - 1:+.2e} from the reference")
print(f"sideways drift |x| / distance fallen: {abs(x[-1]) / (4.0 - hist['y'][-1]):.1e}")
# measured: -1.6e-3 (`fluidem bench settling-disk`, p2b at h = 0.025 and dt = 0.01, reaches 1.7e-5)
assert abs(U_free / U_ref - 1) < 3e-3

# %%
fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
axes[0].plot(t, vy, label="free disk (coupled solver)")
axes[0].axhline(U_ref, color="k", ls="--", label="steady reference")
axes[0].set_xlabel("t")
axes[0].set_ylabel("settling speed −v_y")
axes[0].legend()
axes[1].semilogy(t, np.abs(U_ref - vy), label="|U_ref − v(t)|")
tau = -1.0 / np.polyfit(t[t > 2], np.log(np.abs(U_ref - vy[t > 2])), 1)[0]
axes[1].set_xlabel("t")
axes[1].set_ylabel("distance from terminal speed")
axes[1].set_title(f"exponential approach, time constant {tau:.2f}", fontsize=10)
fig.tight_layout()

# %% [markdown]
# The flow at the end, in the frame of the channel: `fluidem.plotting.figures` draws it from
# the run directory (the tall channel is cropped around the disk).

# %%
figs = figures(out)
for name in figs:
    if name not in ("velocity", "history"):
        plt.close(figs[name])
figs["velocity"]

# %% [markdown]
# ## Stokes flow: Faxén's wall correction
#
# Without inertia the disk reaches its terminal velocity at once, so a few steps suffice. In a
# channel the drag is F = μ U · F*(k), with Faxén's series for a cylinder midway between two
# plane walls:
#
# F* = 4π / (ln(1/k) − 0.9157 + 1.7244 k² − 1.7302 k⁴ + 2.4056 k⁶ − 4.5913 k⁸).

# %%
def faxen(k):
    return 4 * math.pi / (math.log(1 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6
                          - 4.5913 * k**8)


stokes = settling_scene(a=a, density=density, nu=1.0, g=g, h=0.025, dt=0.01, t_end=0.04, element=element).to_dict()
stokes["fluid"]["model"] = "stokes"
sim_s = Simulation(Scene.from_dict(stokes))
speeds = []
sim_s.run(out_dir=None, progress=lambda k, n, t, c: speeds.append(-sim_s.flow.body_velocities[0, 1]))
area = 0.5 * 64 * a**2 * math.sin(2 * math.pi / 64)       # the 64-gon's area
U_faxen = (density - 1.0) * area * g / (1.0 * faxen(a / 0.5))
for k, v in enumerate(speeds, 1):
    print(f"step {k}: U = {v:.6f}, U / U_Faxén − 1 = {v / U_faxen - 1:+.2e}")
# measured: +6.7e-4 at every step
assert max(abs(v / U_faxen - 1) for v in speeds) < 2e-3
