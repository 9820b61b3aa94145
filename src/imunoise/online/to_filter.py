"""The online engine's settings on the one fit → filter mapping, :mod:`imunoise.nav.filter_model` (the door every
entry uses: the engine, ``nav --imu-model``, ``online --imu-model``, the experiments): :func:`filter_axis_models`
reads ``floor``/``fold_tau_s``/``dr``/``qn`` from an :class:`OnlineConfig`. :func:`ekf_axis_model`,
:func:`data_horizon` and :func:`dr_equivalent_rw` are the nav module's, under the names the engine has used."""

from __future__ import annotations

from imunoise.nav import filter_model as _door
from imunoise.nav.defaults import default_axis_models
from imunoise.nav.filter_model import data_horizon, dr_equivalent_rw
from imunoise.nav.filter_model import filter_model as ekf_axis_model
from imunoise.noise.model import Model
from imunoise.online.config import OnlineConfig

__all__ = ["data_horizon", "dr_equivalent_rw", "ekf_axis_model", "filter_axis_models"]


def filter_axis_models(fits: list, freq: float, config: OnlineConfig | None = None,
                       floor: list[Model] | None = None) -> list[Model]:
    """The six models (each carrying its rate) the filter gets from per-axis fits (gyro x,y,z, accel x,y,z):
    :func:`imunoise.nav.filter_model.filter_axis_models` with ``config``'s settings; the one six-axis loop of the
    online engine (:meth:`OnlineNavigator.filter_models`) and the experiments' fixed-model baselines.

    Parameters
    ----------
    fits : list
        Per axis a :class:`~imunoise.noise.estimator.GMWMFit` (or any fit with ``model``, ``freq`` and optionally
        ``wv``), a bare :class:`Model` (at its own rate, ``freq`` when it has none; no horizon), or None (the
        plain default of ``config.ekf.fallback``).
    freq : float
        IMU rate in Hz (the rate of the returned models but those of bare models at another rate).
    config : OnlineConfig, optional
        The mapping settings (default :class:`OnlineConfig`).
    floor : list of Model, optional
        Per-axis plain default models at ``freq`` when already built (default: from ``config.ekf.fallback``).

    Returns
    -------
    list of Model
    """
    config = config or OnlineConfig()
    defaults = floor if floor is not None else default_axis_models(freq, config.ekf.fallback)
    out = _door.filter_axis_models(fits, freq, defaults if config.floor == "default" else [None] * len(fits),
                                   fold_tau_s=config.fold_tau_s, dr=config.dr, qn=config.qn)
    return [defaults[a].with_freq(defaults[a].sample_rate(freq, "the floor")) if f is None else m
            for a, (f, m) in enumerate(zip(fits, out, strict=True))]
