"""In-motion noise learned while driving by rehearsing GNSS outages on data already seen (``gmwm_dyn``): the
filter end of IMU → detection → modelling → filter, after the stops' model (online stage).

Why. Stops show the sensor at rest; while the car drives, vibration, temperature and g-sensitivity change the
errors (the shared drive: std of 10 s means of the estimated gyro errors 58 / 144 / 123 °/h for x/y/z against a
static ADEV at 10 s of 64 / 37 / 6 °/h), and the outage drift depends on how the filter models them. Which
law a vehicle follows is unknown, so the learner is safe first and useful second: it changes the live model only
on evidence that survives the number of candidates it tried, inside the GNSS consistency band, and goes back
when later evidence contradicts a change.

Parts (one concept per module):

* :mod:`~imunoise.online.learner.candidates`: what can be learned (gyro and accelerometer in-motion
  Gauss–Markov, white-noise inflation, departure step; σ on a refined log scale; nothing added always a
  candidate) and how it enters the filter model;
* :mod:`~imunoise.online.learner.rehearsal`: shadow filters and rehearsed outages (one round's scores and NIS);
* :mod:`~imunoise.online.learner.decision`: choose / confirm at α/m on disjoint later rounds / revert; the NIS
  guard on position and velocity;
* :mod:`~imunoise.online.learner.likelihood`: the selectable likelihood statistic (``statistic="likelihood"``,
  EXPERIMENTAL research code): likelihood-ratio tests on the shadows' one-step GNSS innovations, a GNSS σ-scale
  rival, the rehearsal drift as a harm guard;
* :mod:`~imunoise.online.learner.core`: the learner's state (searches, phases, decisions, cost);
* :mod:`~imunoise.online.learner.host`: the navigator's side (live swaps, departure steps, the event log);
* :mod:`~imunoise.online.learner.config`: settings and the evidence carried to the next drive.
"""

from imunoise.noise.moved import renamed
from imunoise.online.learner.candidates import DEFAULT_FAMILIES, Family, LearnedProcess, compose, describe
from imunoise.online.learner.config import MotionNoiseConfig, MotionNoisePrior
from imunoise.online.learner.core import MotionNoiseLearner
from imunoise.online.learner.decision import Verdict, choose, confirm, nis_ok, revert
from imunoise.online.learner.rehearsal import horizontal_distance, ned_offset

__all__ = ["DEFAULT_FAMILIES", "Family", "LearnedProcess", "compose", "describe", "MotionNoiseConfig",
           "MotionNoisePrior", "MotionNoiseLearner", "Verdict", "choose", "confirm", "nis_ok", "revert",
           "horizontal_distance", "ned_offset"]


# the learner's process was called Process, the same name as the noise process of imunoise.noise.processes
__getattr__ = renamed(__name__, {"Process": (lambda: LearnedProcess, "imunoise.online.learner.Process is renamed "
                                 "LearnedProcess (imunoise.noise.processes.Process is the noise process); the old "
                                 "name goes in the next release")})
