"""Settings of the in-motion noise learner and the evidence it carries from one drive to the next."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imunoise.errors import DataError, ModelError
from imunoise.online.learner.candidates import DEFAULT_FAMILIES, Family, LearnedProcess, Spec, describe, spec_from_dicts

__all__ = ["MotionNoiseConfig", "MotionNoisePrior", "STATISTICS"]

STATISTICS = ("drift", "likelihood")  # the decision statistics of the learner (MotionNoiseConfig.statistic)


@dataclass(frozen=True)
class MotionNoisePrior:
    """What the learner learned on earlier drives of the same IMU in the same vehicle: ``spec`` the learned
    processes (the live filter runs them from the first sample; the new drive's searches may revert them),
    ``families`` the refined σ scales to search next, ``rounds`` the rehearsal rounds behind them."""

    spec: Spec = ()
    families: tuple[Family, ...] = DEFAULT_FAMILIES
    rounds: int = 0

    def __post_init__(self) -> None:
        if not all(isinstance(p, LearnedProcess) for p in self.spec) or not all(isinstance(f, Family)
                                                                         for f in self.families):
            raise ModelError("a motion-noise prior needs spec = learned processes and families = σ scales")
        if not (isinstance(self.rounds, int) and self.rounds >= 0):
            raise ModelError(f"motion-noise prior: rounds must be a count ≥ 0, got {self.rounds!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``imunoise online`` writes it as ``metrics.json["motion_noise"]["evidence"]``)."""
        return {"spec": describe(self.spec), "rounds": self.rounds,
                "families": [{"kind": f.kind, "sensor": f.sensor, "centre": f.centre, "ratio": f.ratio,
                              "tc_s": list(f.tc_s)} for f in self.families]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MotionNoisePrior:
        """From :meth:`to_dict`, or from a whole ``metrics.json`` of ``imunoise online --learn-motion-noise``."""
        if isinstance(d, dict) and "motion_noise" in d:
            d = d["motion_noise"]
        if isinstance(d, dict) and "evidence" in d:
            d = d["evidence"]
        if not isinstance(d, dict) or not {"spec", "families", "rounds"} <= set(d):
            raise ModelError("not a motion-noise prior: expected the metrics.json of `imunoise online "
                             "--learn-motion-noise` or a dict with spec, families and rounds")
        try:
            fams = tuple(Family(str(f["kind"]), str(f["sensor"]), float(f["centre"]), float(f["ratio"]),
                                tuple(float(x) for x in f.get("tc_s", ()))) for f in d["families"])
            return cls(spec_from_dicts(d["spec"]), fams, int(d["rounds"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"motion-noise prior: malformed families or rounds ({exc})") from exc

    @classmethod
    def load(cls, path: str | Path) -> MotionNoisePrior:
        """Read a prior from a JSON file (a ``metrics.json`` of ``imunoise online --learn-motion-noise`` or
        :meth:`to_dict` saved)."""
        p = Path(path)
        try:
            d = json.loads(p.read_text())
        except FileNotFoundError as exc:
            raise DataError(f"motion-noise prior {p} does not exist") from exc
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise DataError(f"motion-noise prior {p} is not a readable JSON file: {exc}") from exc
        return cls.from_dict(d)


@dataclass(frozen=True)
class MotionNoiseConfig:
    """Settings of the learner (:mod:`imunoise.online.learner`).

    ``families``: the σ scales searched (:class:`~imunoise.online.learner.candidates.Family`); ``outage_s``:
    length of a rehearsed outage [s]; ``every_s``: one round per this many seconds (≥ ``outage_s``: rehearsed
    outages never overlap); ``warm_rounds``: rounds of a new search's shadows not scored (their models settle);
    ``choose_rounds``, ``confirm_rounds``: scored rounds to choose and, disjoint and later, to confirm;
    ``alpha``: family-wise level of a switch (each confirmation at ``alpha``/m, m candidates) and the level of a
    revert; ``margin``: the confirmed mean log ratio must be below −margin; ``nis_alpha``: two-sided level of the
    NIS band; ``min_speed_mps``: rehearse only while the current model's shadow moves faster; ``min_stop_s``: a
    departure follows a raw static run of at least this; ``prior``: what earlier drives of the same IMU and
    vehicle learned (:class:`MotionNoisePrior`) or None.

    ``statistic``: the evidence of a decision. ``"drift"`` (the default, the reported learner): the log RMS
    drift of the rehearsed outages, paired t tests. ``"likelihood"`` (EXPERIMENTAL research code, not reported): the
    shadows' accumulated one-step GNSS innovation NLL, likelihood-ratio tests against χ²(``lr_df``) at
    1 − ``alpha``/m (:mod:`imunoise.online.learner.likelihood`), every round with fixes counted; ``r_scales``: the
    GNSS σ factors of the R-only nuisance candidates an in-motion change must also beat; ``harm_margin``: the
    rehearsal drift guard (refuse when the chosen candidate's mean log drift ratio over the rehearsed confirm
    rounds exceeds it)."""

    families: tuple[Family, ...] = DEFAULT_FAMILIES
    outage_s: float = 20.0
    every_s: float = 20.0
    warm_rounds: int = 1
    choose_rounds: int = 4
    confirm_rounds: int = 6
    alpha: float = 0.05
    margin: float = 0.01
    nis_alpha: float = 0.01
    min_speed_mps: float = 2.0
    min_stop_s: float = 2.0
    prior: MotionNoisePrior | None = None
    statistic: str = "drift"
    r_scales: tuple[float, ...] = (0.7, 1.4)
    lr_df: int = 1
    harm_margin: float = 0.05

    def __post_init__(self) -> None:
        if self.statistic not in STATISTICS:
            raise ModelError(f"MotionNoiseConfig.statistic must be one of {', '.join(STATISTICS)}, "
                             f"got {self.statistic!r}")
        rs = tuple(float(r) for r in self.r_scales)
        if not all(math.isfinite(r) and r > 0 and r != 1.0 for r in rs) or not (self.lr_df >= 1
                                                                                and self.harm_margin >= 0):
            raise ModelError("MotionNoiseConfig: r_scales finite, > 0 and ≠ 1; lr_df ≥ 1; harm_margin ≥ 0")
        object.__setattr__(self, "r_scales", rs)
        fams = tuple(self.families)
        if not fams or not all(isinstance(f, Family) for f in fams):
            raise ModelError("MotionNoiseConfig.families needs at least one Family (σ scale)")
        for f in fams:
            LearnedProcess(f.kind, f.sensor, f.centre if f.kind != "white" else max(f.centre, 1.01), f.tc_s[0]
                    if f.tc_s else 1.0)  # checks kind, sensor and units
            if not (f.ratio >= 1.0 and math.isfinite(f.ratio)) or (f.kind == "gm" and not f.tc_s):
                raise ModelError(f"MotionNoiseConfig: family {f.kind}/{f.sensor} needs ratio ≥ 1 (and T_c values "
                                 "for gm)")
        object.__setattr__(self, "families", fams)
        if not (self.outage_s > 0 and self.every_s >= self.outage_s):
            raise ModelError(f"MotionNoiseConfig: outage_s > 0 and every_s ≥ outage_s (rehearsed outages must not "
                             f"overlap), got outage_s={self.outage_s!r}, every_s={self.every_s!r}")
        if not (self.warm_rounds >= 0 and self.choose_rounds >= 1 and self.confirm_rounds >= 2):
            raise ModelError("MotionNoiseConfig: warm_rounds ≥ 0, choose_rounds ≥ 1, confirm_rounds ≥ 2")
        if not (0 < self.alpha < 1 and 0 < self.nis_alpha < 1 and self.margin >= 0 and self.min_speed_mps >= 0
                and self.min_stop_s > 0):
            raise ModelError("MotionNoiseConfig: 0 < alpha, nis_alpha < 1; margin, min_speed_mps ≥ 0; "
                             "min_stop_s > 0")
        if self.prior is not None and not isinstance(self.prior, MotionNoisePrior):
            raise ModelError(f"MotionNoiseConfig.prior must be a MotionNoisePrior, got {type(self.prior).__name__}")
