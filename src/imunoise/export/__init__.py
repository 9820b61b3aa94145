"""Export a GMWM model to the noise parameters of VIO/INS stacks
(docs/guide/theory.rst, 'Latent processes' and 'Interfaces').

Kalibr ``imu.yaml``, OpenVINS ``kalibr_imu_chain.yaml`` and ORB-SLAM3 ``IMU.*`` all take two
*continuous-time* densities per sensor — white noise N [u/√Hz] and bias random walk K [u/s/√Hz] — and
discretise them with the update rate f = 1/Δt (σ_d = N·√f per sample, bias step K/√f).

The fitted model is mapped to (N, K) by what the filter will see (:mod:`imunoise.noise.equivalent_noise`, the one
mapping shared with the online filter): the WN + RW pair whose Allan variance best matches the model's, in
log-variance least squares over averaging times from the update period Δt to a horizon (default: the longest
scale of the data the model was fitted on; ``horizon_s`` / ``--horizon S``), each line at or below the
model's AV as in an IEEE Allan reading (K over the whole range, N where the model falls like white noise; a
drift becomes the random walk with its AV at the horizon). Exact closed forms where they exist: WN → N =
σ·√Δt, RW → K = γ/√Δt, QN → white with its per-sample variance 2Q², an AR1 that decorrelates within one
update → white with its zero-frequency density σ/(1−φ)·√Δt (→ σ_GM·√(2T_c)). A Gauss–Markov term is white on
scales ≫ T_c and a random walk on scales ≪ T_c: a slow one (T_c ≫ horizon) goes to K, a fast one to N, and
one in between is neither — its Allan bump is what the pair cannot follow. K is never the Allan-variance
minimum (bias instability). K never exceeds the data's Allan bound min_τ AD(τ)·√(3/τ) over the points with
≥ 3 equivalent degrees of freedom (the densest curve the fit carries, :func:`imunoise.noise.allan.data_curve`): a
fitted RW term that overshoots the data's long-τ AV is capped there, and the file says so beside K.

Beside each written pair: the τ range it was matched on and the worst ratio between the written pair's AV
and each axis model's AV there; a ratio above 2 is a warning (:attr:`SensorNoise.warnings`). Never a zero
or non-finite density: white noise not identified over the range → the largest white line under the
model's AV when the model has a process that decorrelates inside the range, else :class:`ModelError`;
random walk not identified (the model's AV does not rise) → half the largest RW under it, with a note.
Three axes of one sensor are combined by the maximum (default) or the root mean square.
Optional inflation factors (``white=2,rw=10``) multiply the written values and are shown beside them.
Every number is followed by its unit and the words continuous / discrete in a comment.

VINS-Mono/VINS-Fusion, LIO-SAM and FAST-LIO take the same pair under their own conventions, read in their source
(:mod:`~imunoise.export.vins_lio`): VINS discrete standard deviations per sample (N·√(2f), K·√f), LIO-SAM the
continuous (N, K), FAST-LIO discrete variances per sample (N²·f, K²·f).

A model with an in-motion part writes its **in-use** pair (the static pair times the in-use/static factors
estimated from whole drives, each key's comment with the factor, its 95 % interval and the static value;
:mod:`~imunoise.export.in_use`); ``noise="static"`` (``--noise static``) writes the static pair.

The package: :mod:`~imunoise.export.noise` (the (N, K) per axis and per sensor), :mod:`~imunoise.export.formats`
(the text of each format), :mod:`~imunoise.export.vins_lio` (VINS, LIO-SAM, FAST-LIO) and
:mod:`~imunoise.export.files` (writing, reading back, updating in place).
The last piece of the modelling stage of the data path IMU → detection → modelling → filter: it turns a fitted
model into what a filter is configured with, and imports no filter.
"""

from __future__ import annotations

from imunoise.export.files import read_export, update_into, write_export
from imunoise.export.formats import DEFAULT_FILENAMES, FORMATS, export_text, model_sensors, model_topic, required_keys
from imunoise.export.formats import OPENVINS_INTRINSICS as OPENVINS_INTRINSICS
from imunoise.export.formats import OPENVINS_VERSIONS as OPENVINS_VERSIONS
from imunoise.export.formats import ORBSLAM3_VERSIONS as ORBSLAM3_VERSIONS
from imunoise.export.formats import axis_lines as axis_lines
from imunoise.export.noise import NOT_IDENTIFIED as NOT_IDENTIFIED
from imunoise.export.noise import (
    RULE,
    AxisNoise,
    SensorNoise,
    axis_noise,
    density_units,
    format_float,
    infer_sensor,
    parse_inflate,
    sensor_noise,
)
from imunoise.export.noise import SENSORS as SENSORS

__all__ = [
    "FORMATS",
    "DEFAULT_FILENAMES",
    "AxisNoise",
    "SensorNoise",
    "RULE",
    "axis_noise",
    "infer_sensor",
    "model_sensors",
    "sensor_noise",
    "parse_inflate",
    "export_text",
    "write_export",
    "update_into",
    "model_topic",
    "required_keys",
    "read_export",
    "format_float",
    "density_units",
]
