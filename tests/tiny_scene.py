"""The tiny channel scene the output, verbose-progress and sweep tests run (a few seconds each)."""


def tiny_channel(h: float = 0.1, t_end: float = 0.2, element: str = "th", density: float = 1.0,
                 output: str = "") -> str:
    """TOML of a 1 x 0.4 channel past a fixed disk, Navier–Stokes, dt = 0.1; ``output``: lines of an [output] table."""
    return f"""
name = "tiny-channel"
[fluid]
density = {density}
viscosity = 1e-2
model = "navier-stokes"
element = "{element}"
[domain]
box = [0.0, 1.0, 0.0, 0.4]
left = "inflow"
right = "outflow"
bottom = "wall"
top = "wall"
inflow_profile = {{ type = "parabolic", umax = 0.3 }}
[[bodies]]
name = "cylinder"
shape = "disk"
radius = 0.05
position = [0.3, 0.2]
motion = "fixed"
[mesh]
h = {h}
[time]
dt = 0.1
t_end = {t_end}
""" + (f"[output]\n{output}\n" if output else "")
