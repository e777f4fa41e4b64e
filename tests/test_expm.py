"""The numpy-only matrix exponential against scipy's and closed forms."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm

from thermoskin.estimation.model import patch_matrices, van_loan
from thermoskin.params import load_config
from thermoskin.physics.convection import R_w as R_w_of
from thermoskin.physics.expm import expm

SCALES = [1e-8, 1e-3, 0.01, 0.2, 0.9, 2.0, 5.0, 20.0, 300.0]


@pytest.mark.parametrize("n", [1, 2, 3, 5, 10, 14])
@pytest.mark.parametrize("scale", SCALES)
def test_against_scipy_every_degree(n: int, scale: float) -> None:
    """Random matrices whose norms fall in each Padé degree's range (3, 5, 7, 9) and beyond
    (13 with squarings): scipy's result to rounding (its own, amplified by the squarings)."""
    rng = np.random.default_rng(n * 1000 + SCALES.index(scale))
    for _ in range(4):
        A = rng.normal(size=(n, n)) * scale / n
        ref = scipy_expm(A)
        tol = 1e-14 * max(1.0, np.linalg.norm(A, 1)) ** 2
        assert np.abs(expm(A) - ref).max() <= tol * np.abs(ref).max()


def test_closed_forms() -> None:
    """A diagonal matrix, a rotation generator and a nilpotent block."""
    d = np.array([-3.0, 0.5, 1e-4])
    assert np.allclose(expm(np.diag(d)), np.diag(np.exp(d)), rtol=1e-14, atol=0)
    w = 2.5
    R = expm(np.array([[0.0, -w], [w, 0.0]]))
    assert np.allclose(R, [[np.cos(w), -np.sin(w)], [np.sin(w), np.cos(w)]], rtol=0, atol=1e-14)
    N = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    assert np.allclose(expm(7.0 * N), [[1, 7, 24.5], [0, 1, 7], [0, 0, 1]], rtol=1e-15, atol=0)
    assert expm(np.zeros((0, 0))).shape == (0, 0)


def test_model_tables_equal_scipys() -> None:
    """The estimator's Van Loan tables (the matrices it is used on) as scipy gives them."""
    cfg = load_config()
    for v in (0.0, 0.141):
        A, B, S = patch_matrices(cfg, R_w_of(v, cfg.skin))
        t_s = cfg.sampling.t_s
        Phi, Gam, Q = van_loan(A, B, S, t_s)
        n = A.shape[0]
        M = np.zeros((n + 2, n + 2))
        M[:n, :n], M[:n, n:] = A, B
        E = scipy_expm(M * t_s)
        assert np.allclose(Phi, E[:n, :n], rtol=1e-14, atol=1e-18)
        assert np.allclose(Gam, E[:n, n:], rtol=1e-14, atol=1e-18)
        F = np.block([[-A, S], [np.zeros_like(A), A.T]]) * t_s
        G = scipy_expm(F)
        Qs = G[n:, n:].T @ G[:n, n:]
        assert np.allclose(Q, 0.5 * (Qs + Qs.T), rtol=1e-12, atol=1e-30)


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="square"):
        expm(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="NaN"):
        expm(np.array([[np.nan]]))
    with pytest.raises(ValueError, match="real"):
        expm(np.array([[1j]]))


@pytest.mark.parametrize("t_s", [0.02, 0.1, 0.5, 1.0])
def test_van_loan_noise_over_long_intervals(t_s: float) -> None:
    """``Q_d = int_0^t_s e^{A s} S e^{A' s} ds`` against a quadrature of scipy's exponentials,
    and positive semi-definite, at the slow rates ``sampling.t_s`` allows (up to 1 s), where a
    single Van Loan exponential cancelled (a negative eigenvalue at 0.5 s, 5e18 at 1 s)."""
    from scipy.integrate import quad_vec

    cfg = load_config()
    for v in (0.0, 0.141):
        A, B, S = patch_matrices(cfg, R_w_of(v, cfg.skin))
        _, _, Q = van_loan(A, B, S, t_s)
        def integrand(s: float, A: np.ndarray = A, S: np.ndarray = S) -> np.ndarray:
            E = scipy_expm(A * s)
            return E @ S @ E.T

        ref, _ = quad_vec(integrand, 0.0, t_s, epsabs=1e-16, epsrel=1e-11)
        assert np.abs(Q - ref).max() <= 1e-9 * np.abs(ref).max()
        assert np.linalg.eigvalsh(Q).min() >= -1e-12 * np.abs(Q).max()


def test_observe_imports_no_scipy_linalg(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """``observe`` of a log (the estimator's tables and its compiled kernel) does without
    ``scipy.linalg`` (0.15-0.3 s of start-up): neither the tables nor numba's first call import it."""
    from thermoskin.logio import write_log
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS

    cfg = load_config()
    log = tmp_path / "short.csv"
    write_log(log, simulate(SCENARIOS["one-finger"].with_duration(0.5), cfg))
    code = ("import sys\nfrom thermoskin.params import load_config\n"
            "from thermoskin.analysis.observe import observe_file\n"
            f"observe_file({str(log)!r}, {str(tmp_path / 'out.csv')!r}, load_config())\n"
            "print(sorted(m for m in sys.modules if m.startswith('scipy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "scipy.linalg" not in out.stdout, out.stdout
