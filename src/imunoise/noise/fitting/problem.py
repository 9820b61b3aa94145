"""The data side of a GMWM fit (docs/guide/theory.rst, 'GMWM estimator'–5): empirical WV, weight matrix Ω and
normalisation, shared by
every candidate model; guided starting points read off the WV; the GMM sandwich covariance of û.

The data's WV is normalised by its largest value before solving so that bounds and tolerances do not
depend on the data's units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg

from imunoise.errors import DataError, ModelError
from imunoise.noise.fitting.arguments import check_freq
from imunoise.noise.fitting.kernels import wv_and_jacobian
from imunoise.noise.fitting.params import bounds, kind_codes, theta_to_u, thetas_to_u
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, PROCESS_TYPES
from imunoise.noise.wv import WaveletVariance, wavelet_variance
from imunoise.units import required_freq

__all__ = ["GMWMProblem", "prepare", "guided_starts", "param_cov"]

_TYPES = tuple(PROCESS_TYPES.values())


@dataclass(frozen=True)
class GMWMProblem:
    """Everything about the data that a fit needs, shared by all candidate models
    (docs/guide/theory.rst, 'Model selection')."""

    wv: WaveletVariance
    weights: str
    W: np.ndarray  # Ω^{1/2} on the original scale: Ω = WᵀW
    scale: float  # normalisation c: ν̂' = ν̂/c, W' = cW
    tau: np.ndarray
    nuhat_n: np.ndarray
    W_n: np.ndarray
    cov: np.ndarray  # estimated Cov(ν̂) (original scale), for parameter CIs

    @property
    def omega(self) -> np.ndarray:
        return self.W.T @ self.W

    def reweighted(self, theoretical: np.ndarray) -> GMWMProblem:
        """The same problem with Cov(ν̂) re-centred on a model WV (iterated GMM,
            see :func:`imunoise.noise.estimator.gmwm`).

        Cov_θ = S Cov S with S = diag(ν(θ)/ν̂), hence W_θ = W S⁻¹: the data's relative uncertainty and
        correlation are kept, but levels whose ν̂ happened to fall low no longer get inflated weight.

        Parameters
        ----------
        theoretical
            A model's WV at the problem's scales (e.g. :attr:`GMWMFit.theoretical_wv`).

        Returns
        -------
        GMWMProblem
            Same WV and normalisation, reweighted W and Cov(ν̂).
        """
        ratio = self.wv.variance / np.maximum(theoretical, 1e-300 * self.scale)
        W = self.W * ratio[None, :]
        S = 1.0 / ratio
        return GMWMProblem(
            wv=self.wv,
            weights=self.weights,
            W=W,
            scale=self.scale,
            tau=self.tau,
            nuhat_n=self.nuhat_n,
            W_n=np.ascontiguousarray(W * self.scale),
            cov=self.cov * np.outer(S, S),
        )

    def objective(self, model: Model) -> float:
        """(ν̂ − ν(θ))ᵀΩ(ν̂ − ν(θ)) for a model with known parameters (paper Eq. 6 / GOF Eq. 8).

        Parameters
        ----------
        model
            A model with known parameters.

        Returns
        -------
        float
            The objective on the original scale.
        """
        r = self.W @ (self.wv.variance - model.wv(self.tau))
        return float(r @ r)


def _weight_matrix(wv: WaveletVariance, weights: str | np.ndarray) -> tuple[str, np.ndarray]:
    J = len(wv.variance)
    if isinstance(weights, np.ndarray):
        om = np.asarray(weights, dtype=float)
        if om.shape != (J, J):
            raise DataError(f"weight matrix must be {J}×{J} for this WV, got {om.shape}")
        try:
            return "custom", linalg.cholesky(om, lower=False)
        except linalg.LinAlgError as exc:
            raise DataError("the given weight matrix Ω is not symmetric positive definite") from exc
    if weights == "identity":
        return weights, np.eye(J)
    if weights == "fast":
        width = wv.ci_high - wv.ci_low
        return weights, np.diag(1.0 / width)
    cov = np.asarray(wv.cov, dtype=float)
    if weights == "diagonal":
        return weights, np.diag(1.0 / np.sqrt(np.diag(cov)))
    if weights == "efficient":
        # Ω = Cov(ν̂)^{-1}: with cov = LLᵀ, W = L^{-1} gives WᵀW = Ω. Scale to unit diagonal first so the
        # Cholesky sees a correlation matrix; a small ridge keeps near-singular estimates usable.
        s = np.sqrt(np.diag(cov))
        corr = cov / np.outer(s, s)
        corr = 0.5 * (corr + corr.T)
        for ridge in (0.0, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2):
            try:
                Lc = linalg.cholesky(corr + ridge * np.eye(J), lower=True)
                break
            except linalg.LinAlgError:
                continue
        else:
            return "diagonal", np.diag(1.0 / s)
        Winv = linalg.solve_triangular(Lc, np.eye(J), lower=True)
        return weights, Winv / s[None, :]
    raise ModelError(f"unknown weights {weights!r}; use 'efficient', 'diagonal', 'fast' or 'identity'")


def prepare(
    data: Any,
    *,
    freq: float | None = None,
    weights: str | np.ndarray = "efficient",
    robust: bool = False,
    who: str = "gmwm",
) -> GMWMProblem:
    """The problem a GMWM fit solves: WV of ``data``, weight matrix Ω, normalisation
    (docs/guide/theory.rst, 'GMWM estimator'–5).

    Parameters
    ----------
    data
        A 1-D array, a list of static segments (pooled WV), a ready :class:`WaveletVariance`, or a
        :class:`GMWMProblem` (returned as is).
    freq
        Sample rate in Hz, required for data (keyword; none is assumed: :func:`imunoise.units.required_freq`);
        a :class:`WaveletVariance` or :class:`GMWMProblem` carries its own (a different ``freq`` is refused).
    weights
        ``"efficient"`` (Ω = Cov(ν̂)⁻¹), ``"diagonal"``, ``"fast"`` (simts' 1/CI-width²), ``"identity"``
        or a J×J symmetric positive definite matrix.
    robust
        Robust WV estimator (docs/guide/theory.rst, 'Wavelet variance').
    who
        The function named in the message when the rate is missing.

    Returns
    -------
    GMWMProblem
        WV, Ω = WᵀW (``weights`` names what was used: ``"diagonal"`` if the efficient Ω was singular)
        and the normalised copies the kernels solve on.
    """
    if isinstance(data, GMWMProblem | WaveletVariance):
        own = float(data.wv.freq if isinstance(data, GMWMProblem) else data.freq)
        if freq is not None and abs(check_freq(freq) - own) > 1e-9 * own:
            raise DataError(f"{who}: freq={freq!r} but the wavelet variance was computed at {own:g} Hz; drop freq")
        if isinstance(data, GMWMProblem):
            return data
        wv = data
    else:
        freq = required_freq(freq, who)
        wv = wavelet_variance(data, robust=robust, freq=freq)
    if len(wv.variance) < 2:
        raise DataError(f"only {len(wv.variance)} wavelet level(s): need more data to fit a model")
    if not np.all(np.isfinite(wv.variance)) or np.any(wv.variance <= 0):
        raise DataError("the wavelet variance has non-positive or non-finite levels; is the data constant?")
    name, W = _weight_matrix(wv, weights)
    scale = float(np.max(wv.variance))
    tau = np.asarray(wv.scales, dtype=float)
    return GMWMProblem(
        wv=wv,
        weights=name,
        W=W,
        scale=scale,
        tau=tau,
        nuhat_n=np.ascontiguousarray(wv.variance / scale),
        W_n=np.ascontiguousarray(W * scale),
        cov=np.asarray(wv.cov, dtype=float),
    )


def guided_starts(problem: GMWMProblem, kinds: np.ndarray, n_random: int, seed: int) -> np.ndarray:
    """Starting points from the shape of the empirical WV (docs/guide/theory.rst, 'GMWM estimator'), plus seeded
    perturbations.

    Each process starts from its own reading of the empirical WV (:meth:`imunoise.noise.processes.Process.start_values`:
    WN/QN from the finest scale, RW/DR from the coarsest); AR1 peaks sit on the scale grid with amplitudes read
    off the empirical WV.

    Parameters
    ----------
    problem
        The prepared problem (its normalised WV is read).
    kinds
        Kind codes of the structure (:func:`~imunoise.noise.fitting.params.kind_codes`).
    n_random
        Number of seeded random perturbations added to the six base starts.
    seed
        Seed of the perturbations.

    Returns
    -------
    numpy.ndarray
        One start u (unit scale of the normalised problem) per row.
    """
    tau = problem.tau
    nu = problem.nuhat_n
    classes, plan = _start_plan(kinds, len(tau), n_random, seed)

    def build(levels: list[int], fr: dict[str, float], ar_amp: float) -> list[float]:
        theta: list[float] = []
        # AR1 part: peaks of the AR1 WV sit near τ ≈ 3.8 T (T the correlation time in samples), with
        # ν²_peak ≈ 0.19 σ²_GM.
        ar_params = []
        for lev in levels:  # slowest first
            T = max(tau[lev] / 3.8, 0.05)
            phi = math.exp(-1.0 / T)
            var_gm = ar_amp * nu[lev] / 0.19
            ar_params.append((phi, var_gm * (1.0 - phi * phi)))
        i_ar = 0
        for cls in classes:
            if cls is AR1:
                theta += list(ar_params[i_ar])
                i_ar += 1
            else:
                theta += cls.start_values(fr[cls.kind], nu, tau)
        return theta

    starts = [build(levels, fr, amp) for levels, fr, amp in plan]
    return thetas_to_u(starts, kinds, 1.0)


_PLANS: dict[tuple, tuple[list, list]] = {}


def _start_plan(kinds: np.ndarray, J: int, n_random: int, seed: int) -> tuple[list, list]:
    """What :func:`guided_starts` draws does not depend on the data: the classes of the structure and, per start,
    (AR1 levels slowest first, fraction per process, AR1 amplitude), the seeded draws included. Computed once per
    (structure, number of levels, n_random, seed); each selection builds starts for 70-odd candidates from them."""
    key = (kinds.tobytes(), J, n_random, seed)
    plan = _PLANS.get(key)
    if plan is not None:
        return plan
    n_ar = int(np.sum(kinds == AR1.code))
    rng = np.random.default_rng(seed)
    classes = [_TYPES[k] for k in kinds.tolist()]
    out = []
    base_levels = (
        np.unique(np.round(np.linspace(J - 2, 1, n_ar)).astype(int)) if n_ar else np.array([], dtype=int)
    )
    if len(base_levels) < n_ar:
        base_levels = np.arange(n_ar)

    def desc(levels: np.ndarray) -> list[int]:
        return np.sort(levels)[::-1].tolist()

    for f_fine in (0.9, 0.5, 0.1):
        for f_coarse in (0.5, 0.05):
            fr = {cls.kind: f_fine if cls.starts_fine else f_coarse for cls in _TYPES}
            out.append((desc(base_levels), fr, 0.5))
    present = {_TYPES[k].kind for k in kinds}
    for _ in range(n_random):
        levels = np.sort(rng.choice(J, size=n_ar, replace=False)) if n_ar <= J else base_levels
        # one draw per single-parameter process of the original four, always (the seeded sequence), then
        # one per other process present
        fr = {k: float(10 ** rng.uniform(-3, 0)) for k in ("WN", "QN", "RW", "DR")}
        fr.update({k: float(10 ** rng.uniform(-3, 0)) for k, c in PROCESS_TYPES.items()
                   if c is not AR1 and k not in fr and k in present})
        out.append((desc(levels), fr, float(10 ** rng.uniform(-1.5, 0.3))))
    plan = (classes, out)
    if len(_PLANS) < 4096:  # bounded: structures × level counts × seeds seen by one process
        _PLANS[key] = plan
    return plan


def param_cov(problem: GMWMProblem, model: Model) -> np.ndarray | None:
    """GMM sandwich covariance of û, (GᵀΩG)⁻¹GᵀΩVΩG(GᵀΩG)⁻¹ (docs/guide/theory.rst, 'GMWM estimator').

    Parameters
    ----------
    problem
        The problem the model was fitted on (V = its ``cov``).
    model
        The fitted model.

    Returns
    -------
    numpy.ndarray or None
        Covariance in the unconstrained parametrisation (unit scale); parameters that are not identified
        get an infinite variance; None when the matrix cannot be formed.
    """
    kinds = kind_codes(model)
    u = theta_to_u(model.vector, kinds, problem.scale)
    J, P = len(problem.tau), len(u)
    nu, jac = np.empty(J), np.empty((J, P))
    wv_and_jacobian(u, kinds, problem.tau, nu, jac)
    G = jac * problem.scale  # ∂ν/∂u on the original scale
    Om = problem.omega
    # A parameter pinned at its bound (e.g. WN absorbed by a sub-sample AR1) or with no influence on the
    # weighted WV is not identified: it gets an infinite variance instead of a misleading zero-width CI.
    lo, hi = bounds(kinds)
    u1 = theta_to_u(model.vector, kinds, 1.0)
    lo1, hi1 = lo + (u1 - u), hi + (u1 - u)  # same bounds expressed on the unit scale of u1
    influence = np.linalg.norm(problem.W @ G, axis=0)
    ident = (u1 > lo1 + 1e-3) & (u1 < hi1 - 1e-3) & (influence > 1e-8 * max(influence.max(), 1e-300))
    C = np.zeros((P, P))
    np.fill_diagonal(C, np.inf)
    if ident.any():
        Gi = G[:, ident]
        A = Gi.T @ Om @ Gi
        try:
            Ainv = linalg.pinvh(A)
        except (linalg.LinAlgError, ValueError):
            return None
        B = Gi.T @ Om @ problem.cov @ Om @ Gi
        Ci = Ainv @ B @ Ainv
        C[np.ix_(ident, ident)] = 0.5 * (Ci + Ci.T)
    return C if not np.any(np.isnan(C)) else None
