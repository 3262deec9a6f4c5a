"""Drawings for the Taga experiments: stick figures (Figs. 5, 7, 8, 9), neural activity
(Figs. 6, 10) and bifurcation diagrams (Fig. 11).  Matplotlib, Agg backend, host arrays."""

from __future__ import annotations

import jax
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import NullFormatter  # noqa: E402, F401

from jaxgait.taga.model import TagaBody  # noqa: E402

NEURON_LABELS = (
    "1 hip R flex",
    "2 hip R ext",
    "3 hip L flex",
    "4 hip L ext",
    "5 knee R flex",
    "6 knee R ext",
    "7 knee L flex",
    "8 knee L ext",
    "9 ankle R flex",
    "10 ankle R ext",
    "11 ankle L flex",
    "12 ankle L ext",
)
RIGHT, LEFT = "#c0392b", "#2c3e91"


def joint_positions(tb: TagaBody, qpos) -> np.ndarray:
    """(T, 5, 2) world (x, z) of hip, right knee, right ankle, left knee, left ankle [m]."""
    ids = [tb.body.site_id(n) for n in ("hip", "knee_r", "ankle_r", "knee_l", "ankle_l")]
    f = jax.jit(jax.vmap(lambda q: tb.body.sites(q, ids)))
    return np.asarray(f(np.asarray(qpos)))


def stick_figure(ax, pos, idx, terrain_fn=None, lw=0.8, alpha=1.0, right=RIGHT, left=LEFT):
    """Draw the legs at the sample indices ``idx`` of ``pos`` (T, 5, 2)."""
    for i in idx:
        p = pos[i]
        ax.plot(p[[0, 1, 2], 0], p[[0, 1, 2], 1], color=right, lw=lw, alpha=alpha)
        ax.plot(p[[0, 3, 4], 0], p[[0, 3, 4], 1], color=left, lw=lw, alpha=alpha)
    xs = pos[idx][:, :, 0]
    x0, x1 = float(xs.min()) - 0.3, float(xs.max()) + 0.3
    gx = np.linspace(x0, x1, 200)
    gz = np.zeros_like(gx) if terrain_fn is None else terrain_fn(gx)
    ax.plot(gx, gz, color="k", lw=1.0)
    ax.set_aspect("equal")
    ax.set_xlim(x0, x1)
    ax.set_xlabel("x [m]")


def network_activity(fig, t, u, title=""):
    """Twelve stacked traces of the inner states u_i (Figs. 6, 10)."""
    axes = fig.subplots(12, 1, sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(t, u[:, i], lw=0.8, color=RIGHT if (i // 2) % 2 == 0 else LEFT)
        ax.axhline(0.0, color="0.7", lw=0.5)
        ax.set_ylabel(NEURON_LABELS[i], rotation=0, ha="right", va="center", fontsize=7)
        ax.tick_params(labelsize=6)
    axes[-1].set_xlabel("t [s]")
    axes[0].set_title(title, fontsize=9)
    return axes


def save(fig, path):
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def figure(w=8.0, h=4.0):
    return plt.figure(figsize=(w, h))
