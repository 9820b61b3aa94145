"""Where each measurement stream besides GNSS position comes from: the one table the command line, the simulator
and the experiments read (docs/guide/theory.rst, 'Navigation filter').

A :class:`AidingSource` names a registered kind of :mod:`imunoise.nav.streams` and says how its epochs are read
(a text file or a bag topic, checked against the IMU's time base and the GNSS track), simulated from a drive's
truth (seeded) and written (what ``imunoise simulate`` leaves beside ``gnss.txt``, named in ``dataset.json`` under
``key``). Every consumer iterates :data:`SOURCES`: ``nav``, ``online`` and ``experiment`` take each as the option
of :mod:`imunoise.cli.aiding_options` with the same key (``--gnss-vel [FILE]``; that table holds only names and
help, so that building the command line loads nothing numerical), the batch filter as ``run_ekf(streams=...)``,
the online engine as :meth:`~imunoise.online.navigator.OnlineNavigator.add_streams`; the simulator writes each.

Adding a measurement: its ``(dz, H, R)`` module (:mod:`imunoise.nav.measurements`), its kind in
:mod:`imunoise.nav.streams`, its reader under :mod:`imunoise.io`, one entry here and one option in
:mod:`imunoise.cli.aiding_options`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.nav.streams import Epochs

__all__ = ["AidingSource", "SOURCES", "source", "simulate_all", "write_simulated", "gnss_velocity_stream"]


@dataclass(frozen=True)
class AidingSource:
    """One measurement stream's sources (module docstring). ``read(path, imu_t=, gnss=, option=, topic=)`` →
    :class:`~imunoise.nav.streams.Epochs`; ``simulate(drive, seed)`` → Epochs; ``write(path, epochs)``."""

    kind: str
    key: str
    file_name: str
    read: Callable[..., Epochs]
    simulate: Callable[[Any, int], Epochs]
    write: Callable[[Path, Epochs], None]


# -- GNSS velocity --------------------------------------------------------------------------------------------
GNSS_VEL_SIGMA = 0.05
"""1σ of a simulated GNSS velocity [m/s] per NED axis (a consumer receiver's Doppler velocity)."""


def _read_gnss_vel(path, *, imu_t=None, gnss=None, option="--gnss-vel", topic=None) -> Epochs:
    from imunoise.io.gnss_velocity import read_gnss_velocity
    from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity

    f = read_gnss_velocity(path, imu_t=imu_t, gnss=gnss, option=option, topic=topic)
    v = as_gnss_velocity(f.t, f.vel_ned, f.sigma_ned)
    return Epochs("gnss_velocity", v.t, v.vel_ned, v.sigma_ned, v.gate_abs, v.max_reject, dropped=f.dropped,
                  source=str(path))


def gnss_velocity_stream(vel, source: str = "") -> Epochs:
    """The measurement stream of GNSS velocity fixes ``vel`` the caller holds
    (:class:`~imunoise.nav.measurements.gnss_velocity.GnssVelocity`, e.g. from
    :func:`~imunoise.nav.measurements.gnss_velocity.as_gnss_velocity`): its times, NED velocities and σ, its gate's
    guards and its dropped rows, for ``run_ekf(..., streams=[gnss_velocity_stream(vel)])``."""
    return Epochs("gnss_velocity", vel.t, vel.vel_ned, vel.sigma_ned, vel.gate_abs, vel.max_reject,
                  dropped=vel.dropped, source=source)


def _simulate_gnss_vel(drive, seed: int) -> Epochs:
    """The antenna's true velocity at every GNSS epoch plus white noise of :data:`GNSS_VEL_SIGMA`."""
    from imunoise.nav.measurements.gnss_velocity import VEL_GATE_ABS, VEL_MAX_REJECT

    rng = np.random.default_rng([seed, 0x7E1])
    ref = drive.reference_antenna
    t = np.asarray(drive.gnss_full.t, dtype=float)
    v = np.column_stack([np.interp(t, ref.t, ref.vel_ned[:, i]) for i in range(3)])
    v = v + GNSS_VEL_SIGMA * rng.standard_normal(v.shape)
    return Epochs("gnss_velocity", t, v, np.full(v.shape, GNSS_VEL_SIGMA), VEL_GATE_ABS, VEL_MAX_REJECT,
                  source="simulated")


def _write_gnss_vel(path: Path, e: Epochs) -> None:
    from imunoise.io.atomic import atomic_write_text

    rows = np.column_stack([e.t, e.z, e.sigma])
    body = "\n".join(" ".join(f"{x:.6f}" for x in r) for r in rows)
    atomic_write_text(path, "# t[s] vN vE vD [m/s] sN sE sD [m/s] (GNSS antenna velocity)\n" + body + "\n")


# -- odometer ------------------------------------------------------------------------------------------------
ODO_SIM_SIGMA = 0.05
"""1σ of a simulated odometer speed [m/s]."""
ODO_SIM_SF_SIGMA = 0.005
"""1σ of a simulated odometer's scale-factor error (0.5 %; drawn once per drive, seeded)."""


def _odometer_epochs(t, speed, sigma, source: str) -> Epochs:
    from imunoise.nav.measurements.odometer import ODO_GATE_ABS, ODO_MAX_REJECT, ODO_SF_SIGMA, ODO_SIGMA

    s = np.where(np.isfinite(sigma), np.maximum(sigma, 0.005), ODO_SIGMA)
    return Epochs("odometer", np.asarray(t, dtype=float), np.asarray(speed, dtype=float).reshape(-1, 1),
                  np.column_stack([s, np.full(s.size, ODO_SF_SIGMA)]), ODO_GATE_ABS, ODO_MAX_REJECT, source=source,
                  lever=(0.0, 0.0, 0.0))


def _read_odometer(path, *, imu_t=None, gnss=None, option="--odometer", topic=None) -> Epochs:
    from imunoise.io.odometer import read_odometer

    f = read_odometer(path, imu_t=imu_t, gnss=gnss, option=option, topic=topic)
    return _odometer_epochs(f.t, f.speed, f.sigma, str(path))._replace(dropped=f.dropped)


def _simulate_odometer(drive, seed: int) -> Epochs:
    """The body-x speed of the IMU point at the reference epochs (10 Hz by default) times (1 + ε), ε ~ N(0,
    :data:`ODO_SIM_SF_SIGMA`) once per drive, plus white noise of :data:`ODO_SIM_SIGMA`, never below 0."""
    from imunoise.nav.measurements.odometer import forward_speed

    rng = np.random.default_rng([seed, 0x0D0])
    ref = drive.reference
    eps = ODO_SIM_SF_SIGMA * rng.standard_normal()
    v = forward_speed(ref.vel_ned, ref.euler) * (1.0 + eps) + ODO_SIM_SIGMA * rng.standard_normal(ref.t.size)
    e = _odometer_epochs(ref.t, np.maximum(v, 0.0), np.full(ref.t.size, ODO_SIM_SIGMA), f"simulated (ε {eps:+.4%})")
    return e


def _write_odometer(path: Path, e: Epochs) -> None:
    from imunoise.io.atomic import atomic_write_text

    rows = np.column_stack([e.t, e.z[:, 0], e.sigma[:, 0]])
    body = "\n".join(f"{r[0]:.6f} {r[1]:.4f} {r[2]:.4f}" for r in rows)
    atomic_write_text(path, f"# t[s] speed[m/s] sigma[m/s] (vehicle forward speed; {e.source})\n" + body + "\n")


SOURCES: tuple[AidingSource, ...] = (
    AidingSource("gnss_velocity", "gnss_vel", "gnss_vel.txt", _read_gnss_vel, _simulate_gnss_vel, _write_gnss_vel),
    AidingSource("odometer", "odometer", "odometer.txt", _read_odometer, _simulate_odometer, _write_odometer),
)
"""Every measurement source, in :data:`imunoise.nav.streams.KINDS` order."""


def source(key: str) -> AidingSource:
    """The source of manifest key / option destination ``key`` (e.g. ``gnss_vel``)."""
    for s in SOURCES:
        if s.key == key:
            return s
    raise KeyError(f"no measurement source {key!r}; known: {', '.join(s.key for s in SOURCES)}")


def simulate_all(drive, seed: int, keys=None) -> dict[str, Epochs]:
    """Every source's simulated epochs of ``drive`` (or those of ``keys``), by key."""
    return {s.key: s.simulate(drive, seed) for s in SOURCES if keys is None or s.key in keys}


def write_simulated(drive, out_dir: str | Path, seed: int) -> dict[str, str]:
    """Write every source's simulated epochs of ``drive`` into ``out_dir`` (which ``drive.write`` filled) and name
    them in its ``dataset.json`` under each source's key; returns {key: file name}."""
    out = Path(out_dir)
    names = {}
    for key, e in simulate_all(drive, seed).items():
        s = source(key)
        s.write(out / s.file_name, e)
        names[key] = s.file_name
    manifest = out / "dataset.json"
    if manifest.exists():
        m = json.loads(manifest.read_text())
        m.update(names)
        manifest.write_text(json.dumps(m, indent=1))
    return names
