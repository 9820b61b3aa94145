"""Issue 22, acceptance 1: every export of the five ADIS16405 units and of the drive's ``calibrate``, read back
the way OpenVINS >= 2.7, ORB-SLAM3 v1.0 (after ``--into`` its EuRoC settings, and a legacy one) and Kalibr read it.

    .venv/bin/python scripts/export_clients_check.py [--data ../shared/data] [--out out/export_clients]

Per ADIS unit: ``imunoise fit UNIT.npz --columns gyro_x,...,accel_z --auto --out OUT/unitK`` (the file states
its units and rate). For the
drive: its IMU and GNSS written as a ROS 1 bag (topic /imu, as in the README), then ``imunoise calibrate
drive.bag --force --out OUT/drive``. Then for each model, through the CLI: ``export --force --to openvins`` and
``--to kalibr``
(new files), ``export --to orbslam3 --into`` copies of tests/fixtures/orbslam3_euroc_v1.yaml (File.version
"1.0") and orbslam3_euroc_legacy.yaml (no File.version). Each file is read with cv2.FileStorage (OpenVINS,
ORB-SLAM3: OpenCV readers) or PyYAML (Kalibr), making the reads each tool makes (the sources are cited in
tests/export/test_export_clients.py), and every value compared with ours (:func:`imunoise.export.sensor_noise`).
Prints a Markdown table (unit, format, keys read, max relative difference, rostopic) and writes it to
OUT/export_clients.md. Needs opencv-python-headless and rosbags. A few minutes. ``--force``: axes whose fit
leaves its WV band (every axis of the drive, 14 of 30 ADIS axes) are exported with ``# WARNING`` lines at the
top of each file; the check reads those files as the tools do, warning lines included.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FIX = REPO / "tests" / "fixtures"
KALIBR = ("gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
          "accelerometer_random_walk")
ORB = ("IMU.NoiseGyro", "IMU.GyroWalk", "IMU.NoiseAcc", "IMU.AccWalk")
INTRINSICS = {"Tw": 1.0, "R_IMUtoGYRO": 1.0, "Ta": 1.0, "R_IMUtoACC": 1.0, "Tg": 0.0}  # diagonal value


class Rejected(Exception):
    """A read the tool makes failed."""


def _need(cond: bool, what: str) -> None:
    if not cond:
        raise Rejected(what)


def read_openvins(path: Path) -> dict:
    """OpenVINS' imu0 reads (VioManagerOptions.h print_and_load_noise/print_and_load_state, StateOptions.h,
    ROS1Visualizer.cpp; YamlParser in opencv_yaml_parse.h)."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    _need(fs.isOpened() and "imu0" in fs.root().keys(), "imu0 not found")
    imu = fs.getNode("imu0")
    keys = list(imu.keys())
    _need(len(keys) == len(set(keys)), "duplicate keys in imu0")
    out = {}
    for k in KALIBR:
        _need(k in keys and imu.getNode(k).isReal(), f"{k} missing or not a number")
        out[k] = imu.getNode(k).real()
    _need(imu.getNode("rostopic").isString(), "rostopic missing")
    out["rostopic"] = imu.getNode("rostopic").string()
    _need(imu.getNode("model").string() in ("kalibr", "calibrated", "rpng"), "model missing or invalid")
    out["model"] = imu.getNode("model").string()
    for k, diag in INTRINSICS.items():
        node = imu.getNode(k)
        _need(k in keys and node.isSeq() and node.size() == 3, f"{k} missing or not 3 rows")
        m = [[node.at(r).at(c).real() for c in range(3)] for r in range(3)]
        _need(m == [[diag if r == c else 0.0 for c in range(3)] for r in range(3)], f"{k} is not the expected matrix")
        out[k] = m
    out["update_rate"] = imu.getNode("update_rate").real()
    return out


def read_orbslam3(path: Path) -> dict:
    """ORB-SLAM3 v1.0: System.cc (File.version "1.0" -> Settings::readIMU, else Tracking::ParseIMUParamFile)."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    _need(fs.isOpened(), "not readable by cv::FileStorage")
    keys = list(fs.root().keys())
    _need(len(keys) == len(set(keys)), "duplicate keys")
    v = fs.getNode("File.version")
    legacy = not (not v.empty() and v.isString() and v.string() == "1.0")
    out: dict = {"legacy": legacy}
    for k in ORB:
        node = fs.getNode(k)
        _need(not node.empty() and (node.isReal() or (not legacy and node.isInt())), f"{k} missing or not real")
        out[k] = node.real()
    f = fs.getNode("IMU.Frequency")
    _need(f.isInt() if legacy else (f.isReal() or f.isInt()), "IMU.Frequency missing" + (" or not an integer"
                                                                                         if legacy else ""))
    out["IMU.Frequency"] = f.real()
    name = "Tbc" if legacy else "IMU.T_b_c1"
    tbc = fs.getNode(name).mat()
    _need(tbc is not None and tbc.shape == (4, 4), f"{name} missing")
    out[name] = "4x4"
    out["File.version"] = "legacy (none)" if legacy else "1.0"
    return out


def read_kalibr(path: Path) -> dict:
    """Kalibr's ImuParameters (ConfigReader.py): yaml.safe_load, rostopic str, update_rate > 0, densities > 0."""
    import yaml

    d = yaml.safe_load(path.read_text())
    _need(isinstance(d.get("rostopic"), str), "rostopic missing")
    _need(d.get("update_rate", 0) > 0, "update_rate missing")
    for k in KALIBR:
        _need(k in d and d[k] > 0, f"Field '{k}' missing")
    return d


def _rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


def check(name: str, model_path: Path, folder: Path, rows: list[str], bag_topic: str | None,
          written: tuple[str, ...] = ()) -> int:
    """Export every format through the CLI (``written``: formats the fit/calibrate run already exported into
    ``folder``), read each back, one row per file; returns the number of failures."""
    from imunoise.cli import main
    from imunoise.export import sensor_noise
    from imunoise.noise.imu_model import load_model

    model = load_model(model_path)
    g, a = sensor_noise(model, "gyro"), sensor_noise(model, "accel")
    ours = dict(zip(KALIBR, (g.noise_density, g.random_walk, a.noise_density, a.random_walk)))
    ours.update(dict(zip(ORB, ours.values())))
    fails = 0
    jobs = [("openvins", folder / "kalibr_imu_chain.yaml", None), ("kalibr", folder / "imu.yaml", None),
            ("orbslam3 --into v1.0", folder / "EuRoC_v1.yaml", "orbslam3_euroc_v1.yaml"),
            ("orbslam3 --into legacy", folder / "EuRoC_legacy.yaml", "orbslam3_euroc_legacy.yaml")]
    for fmt, path, fixture in jobs:
        tool = fmt.split()[0]
        if fixture:
            shutil.copyfile(FIX / fixture, path)
            code = main(["export", str(model_path), "--force", "--to", tool, "--into", str(path)])
        elif tool in written:
            code = 0
            fmt += " (calibrate --export)"
        else:
            code = main(["export", str(model_path), "--force", "--to", tool, "--out", str(path)])
        try:
            _need(code == 0, f"export exit {code}")
            got = {"openvins": read_openvins, "kalibr": read_kalibr, "orbslam3": read_orbslam3}[tool](path)
            names = ORB if tool == "orbslam3" else KALIBR
            diff = max(_rel(got[k], ours[k]) for k in names)
            rate_key = "IMU.Frequency" if tool == "orbslam3" else "update_rate"
            diff = max(diff, _rel(got[rate_key], model.freq_hz if "legacy" not in fmt else round(model.freq_hz)))
            topic = got.get("rostopic", "–")
            ok = diff <= 1e-15 and (tool == "orbslam3" or bag_topic is None or topic == bag_topic)
            keys = [k for k in got if k not in ("legacy", "gyro_discrete")]
            bak = " (backup kept)" if fixture and path.with_name(path.name + ".bak").exists() else ""
            rows.append(f"| {name} | {fmt}{bak} | {len(keys)}: {', '.join(keys)} | {diff:.1e} | {topic} | "
                        f"{'pass' if ok else 'FAIL'} |")
        except (Rejected, KeyError) as exc:
            ok = False
            rows.append(f"| {name} | {fmt} | rejected: {exc} | – | – | FAIL |")
        fails += not ok
    return fails


def main(argv: list[str] | None = None) -> int:
    from imunoise.cli import main as cli

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "data"))
    ap.add_argument("--out", default="out/export_clients")
    args = ap.parse_args(argv)
    data, out = Path(args.data), Path(args.out)
    if not (data / "imudata_adis16405").is_dir():
        data = Path("/work/shared/data")
    out.mkdir(parents=True, exist_ok=True)
    rows = ["| data | format | keys read as the tool reads them | max rel. diff vs ours | rostopic | |",
            "|---|---|---|---|---|---|"]
    t0 = time.perf_counter()
    fails = 0
    for u in range(1, 6):
        folder = out / f"unit{u}"
        shutil.rmtree(folder, ignore_errors=True)
        code = cli(["fit", str(data / "imudata_adis16405" / f"adis16405_unit{u}.npz"), "--columns",
                    "gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z", "--auto", "--out", str(folder)])
        if code:
            rows.append(f"| ADIS unit {u} | fit | exit {code} | – | – | FAIL |")
            fails += 1
            continue
        fails += check(f"ADIS unit {u}", folder / "imu_model.json", folder, rows, None)
        print(f"unit {u} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    from imunoise.io.kfgins import read_gnss, read_imu
    from imunoise.io.navinput import write_nav_bag

    drive = REPO / "data" / "drive_0708"
    folder = out / "drive"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    bag = write_nav_bag(folder / "drive.bag", read_imu(drive / "imu_body_inc.txt.gz"),
                        read_gnss(drive / "gnss_rtk.txt"))
    code = cli(["calibrate", str(bag), "--force", "--export", "openvins", "--export", "kalibr",
                "--out", str(folder / "calib")])
    if code:
        rows.append(f"| drive_0708 calibrate | – | exit {code} | – | – | FAIL |")
        fails += 1
    else:
        fails += check("drive_0708 calibrate (bag topic /imu)", folder / "calib" / "imu_model.json", folder / "calib",
                       rows, "/imu", written=("openvins", "kalibr"))
    md = ["# Issue 22, acceptance 1: exports read back as the tools read them", "",
          f"`python scripts/export_clients_check.py`; {time.perf_counter() - t0:.0f} s; {fails} failure(s).", "",
          *rows]
    text = "\n".join(md) + "\n"
    (out / "export_clients.md").write_text(text)
    print(text)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
