"""Write ``notebooks/NAME.ipynb`` from ``notebooks/NAME.py``, executed, with its outputs.

    pip install -e ".[notebooks]"
    python notebooks/tools/execute.py                 # every walkthrough
    python notebooks/tools/execute.py moving_mesh     # one

The script is the source (edit it, not the notebook); the notebook is its jupytext
``ipynb`` twin run top to bottom in a fresh kernel (nbclient, the ``python3`` kernel of
ipykernel), in ``notebooks/``, with matplotlib's inline backend so the figures are kept.
``tests/test_notebooks.py`` checks that both hold the same cells and that the notebook ran.
"""

import os
import sys
import time
from pathlib import Path

import jupytext
from nbclient import NotebookClient

HERE = Path(__file__).resolve().parents[1]


def execute(name: str, timeout: int = 900) -> float:
    """Execute ``HERE/name.py`` into ``HERE/name.ipynb``; returns the wall seconds."""
    nb = jupytext.read(HERE / f"{name}.py")
    env_backend = os.environ.pop("MPLBACKEND", None)  # the kernel must use the inline backend
    try:
        t0 = time.perf_counter()
        # no per-cell timestamps: a re-execution changes only what the cells print and draw
        NotebookClient(nb, timeout=timeout, kernel_name="python3", record_timing=False,
                       resources={"metadata": {"path": str(HERE)}}).execute()
        seconds = time.perf_counter() - t0
    finally:
        if env_backend is not None:
            os.environ["MPLBACKEND"] = env_backend
    jupytext.write(nb, HERE / f"{name}.ipynb")
    return seconds


if __name__ == "__main__":
    names = sys.argv[1:] or sorted(p.stem for p in HERE.glob("*.py"))
    for n in names:
        print(f"{n}: {execute(n):.1f} s", flush=True)
