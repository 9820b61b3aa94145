"""Input and output of records (docs/guide/theory.rst, 'Conventions' and 'Interfaces'), the first stage of the data path
IMU → detection →
modelling → filter: the KF-GINS text formats (:mod:`~imunoise.io.kfgins`), tables (:mod:`~imunoise.io.tabular`),
ROS bags (:mod:`~imunoise.io.rosbag`), RTKLIB solutions (:mod:`~imunoise.io.rtklib`), GPS time
(:mod:`~imunoise.io.gpstime`), the one IMU entry point :func:`~imunoise.io.imu_input.read_imu_source`, the
navigation inputs from any of these (:mod:`~imunoise.io.navinput`),
dataset manifests (:mod:`~imunoise.io.dataset`), text/JSON reading and atomic writes (:mod:`~imunoise.io.files`,
:mod:`~imunoise.io.atomic`). Everything leaves in SI with checked time stamps. It imports only
:mod:`imunoise.errors` and :mod:`imunoise.units`.
"""
