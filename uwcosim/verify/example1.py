"""Seed 000 Example 1: Galerkin solution of a parabolic PDE with a known exact solution.

    u_t = u_xx - x^2 u + (sin t + cos t + 3x) exp(-x^2/2),   u(x, 0) = x exp(-x^2/2)   (eq. 52)
    u(x, t) = (sin t + x) exp(-x^2/2)                                                   (eq. 53)

The projection filter's machinery (:mod:`uwcosim.filters.projection.series` and the Galerkin
matrix of :mod:`uwcosim.filters.projection.prediction`) discretizes it on
``[-L, L]`` with the ``2K+1`` complex exponentials ``q = -K..K``: Galerkin matrix ``A`` of
``d2/dx2 - x^2`` (eqs. 41-42, inner products by FFT quadrature), projected source and initial
condition. The source is ``(sin t + cos t) a(x) + b(x)``, so the augmented state
``z = [m, sin t, cos t, 1]`` obeys the autonomous linear system ``z' = A_aug z`` and the time
integration is exact: ``z(t + h) = expm(A_aug h) z(t)``.

The half-width balances the two error sources: the truncation error ``~exp(-(pi K / L)^2 / 2)``
and the periodic-wrap error ``~exp(-L^2 / 2)`` are equal for ``L = sqrt(pi K)`` (at least 6 so that
the error window [-5, 5] lies well inside).

``python -c "from uwcosim.verify import run_example1; run_example1(None)"`` (or, once wired,
``uwcosim verify example1``) prints the table of maximum errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from uwcosim.filters.projection import series as po
from uwcosim.filters.projection.prediction import galerkin_matrix

T_END = 10.0
H = 0.1  # output step (s): Figure 2 draws the solution every 0.1 s
X_ERR = np.linspace(-5.0, 5.0, 1001)  # error window of the paper's figures


def exact(x: np.ndarray, t: float) -> np.ndarray:
    """``u(x, t) = (sin t + x) exp(-x^2 / 2)`` (eq. 53)."""
    return (np.sin(t) + x) * np.exp(-0.5 * x**2)


def half_width(K: int) -> float:
    """Default interval half-width ``max(sqrt(pi K), 6)``."""
    return max(float(np.sqrt(np.pi * K)), 6.0)


@dataclass
class Example1Run:
    """Solution of one ``K``: ``u[i]`` on :data:`X_ERR` at ``times[i]``."""

    K: int
    L: float
    times: np.ndarray
    u: np.ndarray

    @property
    def n_basis(self) -> int:
        return 2 * self.K + 1

    def errors(self) -> np.ndarray:
        ref = np.array([exact(X_ERR, t) for t in self.times])
        return self.u - ref


def solve(K: int, L: float | None = None, M: int | None = None) -> Example1Run:
    """Galerkin solution with ``2K+1`` basis functions on ``[-L, L]``, every :data:`H` seconds."""
    L = half_width(K) if L is None else float(L)
    M = M or po.fft_size(max(16 * (2 * K + 1), 512))
    basis = po.SpectralBasis([-L], [2 * L], K, M)
    x = basis.axes()[0]
    g = np.exp(-0.5 * x**2)
    A = galerkin_matrix(basis, c0=-(x**2), c2=[[np.ones(1)]])  # u_xx - x^2 u
    a = po.from_grid(g, basis)  # projected source terms (eq. 45 quadrature)
    b = po.from_grid(3.0 * x * g, basis)
    m0 = po.from_grid(x * g, basis)  # u(x, 0)
    N = basis.size
    Aaug = np.zeros((N + 3, N + 3), dtype=complex)
    Aaug[:N, :N] = A
    Aaug[:N, N] = a  # sin t
    Aaug[:N, N + 1] = a  # cos t
    Aaug[:N, N + 2] = b  # 1
    Aaug[N, N + 1] = 1.0  # (sin t)' = cos t
    Aaug[N + 1, N] = -1.0  # (cos t)' = -sin t
    step = expm(Aaug * H)
    z = np.concatenate([m0, [0.0, 1.0, 1.0]])
    n_out = int(round(T_END / H))
    times = H * np.arange(n_out + 1)
    E = po.axis_matrix(X_ERR, basis.lo[0], basis.length[0], K)
    u = np.empty((n_out + 1, X_ERR.size))
    for i in range(n_out + 1):
        u[i] = (E @ z[:N]).real
        z = step @ z
    return Example1Run(K, L, times, u)


@dataclass
class Example1Result:
    """Maximum (and RMS) error over x in [-5, 5] at t = 1..10 s for each K."""

    Ks: tuple[int, ...]
    times: np.ndarray
    max_error: np.ndarray  # [len(times), len(Ks)]
    rms_error: np.ndarray
    half_widths: tuple[float, ...]
    figures: list[Path] = field(default_factory=list)

    def format(self) -> str:
        head = "t (s) " + "".join(f"{f'K={k} ({2 * k + 1} fns)':>17}" for k in self.Ks)
        lines = [
            "Example 1 (seed 000, eqs. 52-53): max |u_K - u| over x in [-5, 5]",
            "interval [-L, L], L = " + ", ".join(f"{h:.2f}" for h in self.half_widths),
            head,
        ]
        for i, t in enumerate(self.times):
            lines.append(f"{t:5.1f} " + "".join(f"{e:17.3e}" for e in self.max_error[i]))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.format()


def run_example1(
    out_dir: Path | None = None, Ks: tuple[int, ...] = (4, 8, 16, 32), echo: bool = True
) -> Example1Result:
    """Solve Example 1 for each ``K``, print the error table, draw Figures 2-4 into ``out_dir``."""
    Ks = tuple(int(k) for k in Ks)
    runs = [solve(k) for k in Ks]
    every = int(round(1.0 / H))
    sel = slice(every, None, every)  # t = 1, 2, ..., 10
    times = runs[0].times[sel]
    errs = [r.errors()[sel] for r in runs]
    result = Example1Result(
        Ks,
        times,
        np.stack([np.abs(e).max(axis=1) for e in errs], axis=1),
        np.stack([np.sqrt(np.mean(e**2, axis=1)) for e in errs], axis=1),
        tuple(r.L for r in runs),
    )
    if out_dir is not None:
        result.figures = draw_figures(runs, Path(out_dir))
    if echo:
        print(result.format())
        for p in result.figures:
            print(f"wrote {p}")
    return result


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def draw_figures(runs: list[Example1Run], out_dir: Path) -> list[Path]:
    """Figures 2-4 of the paper: solution against exact, error, RMS error (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    best = runs[-1]
    small = runs[0]

    fig, axs = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, run in zip(axs, (small, best), strict=True):
        for i in range(0, best.times.size, 10):
            t = run.times[i]
            ax.plot(X_ERR, exact(X_ERR, t), color="0.6", lw=2.5)
            ax.plot(X_ERR, run.u[i], lw=1.0, label=f"t={t:.0f} s" if i % 20 == 0 else None)
        ax.set_title(f"PFM K={run.K} ({run.n_basis} basis functions) vs exact (grey)")
        ax.set_xlabel("x")
    axs[0].set_ylabel("u(x, t)")
    axs[1].legend(fontsize=7, ncol=2)
    fig.suptitle("Example 1 (eq. 52): Galerkin solution and exact solution (eq. 53)")
    paths.append(_save(fig, out_dir / "example1_fig2_solution.png"))

    fig, axs = plt.subplots(1, 2, figsize=(11, 4.2))
    for run in runs:
        err = np.abs(run.errors())
        axs[0].semilogy(run.times[1:], err[1:].max(axis=1), label=f"K={run.K}")
        axs[1].semilogy(X_ERR, np.maximum(err[-1], 1e-18), label=f"K={run.K}")
    axs[0].set_xlabel("t (s)")
    axs[0].set_ylabel("max |error| over x in [-5, 5]")
    axs[1].set_xlabel("x")
    axs[1].set_ylabel("|error| at t = 10 s")
    for ax in axs:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Example 1: estimation error of the projection (Figure 3)")
    paths.append(_save(fig, out_dir / "example1_fig3_error.png"))

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for run in runs:
        rms = np.sqrt(np.mean(run.errors() ** 2, axis=1))
        ax.semilogy(run.times[1:], rms[1:], label=f"K={run.K}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("RMS error over x in [-5, 5]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Example 1: RMS error (Figure 4)")
    paths.append(_save(fig, out_dir / "example1_fig4_rms.png"))
    return paths
