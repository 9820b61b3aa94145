"""Vehicles of several drives on the simulator (``--vehicle-drives K``; docs/guide/theory.rst, 'Experiments'): the
K drives of vehicle ``seed`` share the IMU (its noise models, turn-on bias statistics and motion law: the
scenario keywords) and the vehicle (lever arm, driving style), and differ in route, stops and every random draw;
every method is scored on the **last** drive, which is the drive of ``seed`` itself, so K = 1 is exactly the
single-drive evidence. The earlier drives are those of seed + k · :data:`PRIOR_SEED_OFFSET`, k = K − 1 … 1
(oldest first), the same drives the warm methods learn from (:mod:`imunoise.experiments.dense_warm`); a method
that learns from the vehicle's earlier drives gets them with GNSS in the run's regime, its noise seeded like a
drive's own (:func:`learning_drives`). With a replayed recording (``--imu-noise``) each drive of a vehicle
replays its own stretch of the unit's recording, disjoint from the others' (:mod:`imunoise.sim.replay`,
:func:`imunoise.experiments.dense_warm.earlier_kw`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from imunoise.errors import ModelError
from imunoise.experiments.common import Scenario
from imunoise.experiments.dense_warm import PRIOR_SEED_OFFSET, earlier_kw
from imunoise.experiments.gnss_regimes import GnssRegime

__all__ = ["vehicle_seeds", "check_vehicle_drives", "earlier_scenarios", "learning_drives"]


def check_vehicle_drives(k: Any) -> int:
    """``--vehicle-drives`` as an int ≥ 1, else a one-line :class:`ModelError`."""
    try:
        n = int(k)
    except (TypeError, ValueError):
        n = 0
    if n < 1 or str(k).strip() not in (str(n), f"+{n}"):
        raise ModelError(f"--vehicle-drives must be a whole number of drives >= 1 (1: one drive per vehicle, 2: "
                         f"learn on one and score the next), got {k!r}")
    return n


def vehicle_seeds(seed: int, k: int) -> list[int]:
    """The simulator seeds of the ``k`` drives of vehicle ``seed``, oldest first; the last is ``seed`` (scored)."""
    k = check_vehicle_drives(k)
    return [int(seed) + j * PRIOR_SEED_OFFSET for j in range(k - 1, 0, -1)] + [int(seed)]


def earlier_scenarios(seed: int, n: int, have: Sequence[Scenario] = (), **scen_kw: Any) -> list[Scenario]:
    """The ``n`` drives before drive ``seed`` in the warm methods' numbering: element k − 1 is the drive of seed +
    k · :data:`PRIOR_SEED_OFFSET` (newest first); ``have`` are the first ones already simulated."""
    from imunoise.experiments.common import simulate_scenario

    out = list(have[:n])
    for k in range(len(out) + 1, n + 1):
        out.append(simulate_scenario(int(seed) + k * PRIOR_SEED_OFFSET, n_outages=0, **earlier_kw(scen_kw, k)))
    return out


def learning_drives(seed: int, k: int, earlier: Sequence[Scenario], regime: GnssRegime,
                    noise_seed: int) -> list[tuple[Scenario, Any]]:
    """The ``k − 1`` earlier drives of vehicle ``seed``, oldest first, each with its GNSS in ``regime`` (noise
    seeded ``1_000_003 · drive seed + noise_seed``, as the scored drive's): what a method that learns from the
    vehicle's earlier drives sees. ``earlier`` as :func:`earlier_scenarios` gives them (at least k − 1)."""
    n = check_vehicle_drives(k) - 1
    if len(earlier) < n:
        raise ModelError(f"vehicle {seed}: {n} earlier drive(s) needed, {len(earlier)} simulated")
    return [(earlier[j - 1], regime.apply(earlier[j - 1].gnss, 1_000_003 * (int(seed) + j * PRIOR_SEED_OFFSET)
                                          + noise_seed)) for j in range(n, 0, -1)]
