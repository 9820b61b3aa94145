"""Narrowband lines in static IMU data: found in the spectrum before the broadband noise model is fitted,
reported per axis, and removed from the data the model is fitted to (:mod:`imunoise.lines.detect`,
:mod:`imunoise.lines.suppress`).

A line is a band of the power spectral density that stands above the axis's broadband floor (a rig, a
timing source or an engine at idle, not a noise process of the sensor). No process of the GMWM family has a
spectrum with a peak, so a fit to data holding one compromises across every scale; the export's white-noise
density then misreads the data by the line's share (ADIS16405 gyro_z: 17–24 % above the Allan deviation at
1 s). Suppressing the band before fitting leaves the broadband noise the exported (N, K) pair stands for.

On the data path (IMU → detection → modelling → filter) it sits beside detection, before modelling: it takes
SI arrays, imports only numpy and scipy, and hands the modelling line-free data and the lines to report.
"""

from imunoise.lines.detect import Line, find_lines, lines_text
from imunoise.lines.suppress import remove_lines, suppress_lines

__all__ = ["Line", "find_lines", "lines_text", "remove_lines", "suppress_lines"]
