"""``export --into`` on settings files written in ways the tools accept but a line editor can break: a YAML anchor
whose alias is elsewhere, a UTF-8 byte-order mark, flow style; and the paths it cannot use (a folder, a folder it
cannot write in). Each: the tool's reader still reads the file, or one line naming ``--into FILE`` and the fix,
exit 2, nothing written.
"""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import pytest
import yaml

from imunoise.cli import main
from imunoise.export import sensor_noise
from imunoise.noise.estimator import gmwm
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model

FIX = Path(__file__).resolve().parents[1] / "fixtures"
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


@pytest.fixture(scope="module")
def model_path(tmp_path_factory) -> Path:
    fits = {}
    for a in AXES:
        gyro = a.startswith("gyro")
        p = {"WN.sigma2": 1e-6 if gyro else 4e-4, "RW.gamma2": 1e-12 if gyro else 1e-9}
        x = Model.parse("WN+RW").with_params(p).simulate(2**12, seed=3)
        fits[a] = gmwm("WN+RW", x, freq=200.0, unit="rad/s" if gyro else "m/s²", n_random=4, n_local=2)
    return ImuModel.from_fits(fits, source={"topic": "/imu0"}).save(tmp_path_factory.mktemp("m") / "imu_model.json")


def _into(model_path: Path, fmt: str, into: Path, capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["export", str(model_path), "--to", fmt, "--into", str(into)])
    return code, capsys.readouterr().err


def test_an_anchor_is_kept_so_its_alias_still_resolves(tmp_path, model_path, capsys):
    """Kalibr's ImuParameters reads the file with yaml.safe_load: an alias to a dropped anchor fails to load."""
    path = tmp_path / "imu.yaml"
    text = (FIX / "kalibr_imu.yaml").read_text()
    text = text.replace("gyroscope_noise_density:     ", "gyroscope_noise_density: &gyro_n ", 1)
    path.write_text(text + "gyroscope_noise_density_copy: *gyro_n  # a second reader of the same value\n")
    code, err = _into(model_path, "kalibr", path, capsys)
    assert code == 0, err
    data = yaml.safe_load(path.read_text())  # raised "found undefined alias 'gyro_n'" when the anchor was dropped
    ours = sensor_noise(ImuModel.load(model_path), "gyro").noise_density
    assert data["gyroscope_noise_density"] == data["gyroscope_noise_density_copy"] == ours
    assert "gyroscope_noise_density: &gyro_n " in path.read_text()


def test_a_tag_before_the_value_is_kept(tmp_path, model_path, capsys):
    path = tmp_path / "imu.yaml"
    stock = "update_rate:" + " " * 17 + "500.0"
    text = (FIX / "kalibr_imu.yaml").read_text().replace(stock, "update_rate: !!float 500.0")
    path.write_text(text)
    assert _into(model_path, "kalibr", path, capsys)[0] == 0
    assert yaml.safe_load(path.read_text())["update_rate"] == 200.0 and "update_rate: !!float 200.0" in path.read_text()


def test_a_byte_order_mark_does_not_hide_the_first_key(tmp_path, model_path, capsys):
    path = tmp_path / "imu.yaml"
    original = (FIX / "kalibr_imu.yaml").read_text()
    first = next(ln.split(":")[0] for ln in original.splitlines() if ln and not ln.startswith("#"))
    path.write_bytes(b"\xef\xbb\xbf" + original.encode())
    assert _into(model_path, "kalibr", path, capsys)[0] == 0
    raw = path.read_bytes()
    assert raw.startswith(b"\xef\xbb\xbf") and raw.count(b"\xef\xbb\xbf") == 1  # kept, once
    text = raw.decode("utf-8-sig")
    assert sum(ln.startswith(f"{first}:") for ln in text.splitlines()) == 1  # rewritten, not appended again
    assert len(text.splitlines()) == len(original.splitlines())
    assert (tmp_path / "imu.yaml.bak").read_bytes() == b"\xef\xbb\xbf" + original.encode()
    assert yaml.safe_load(path.read_text(encoding="utf-8"))[first] > 0  # Kalibr's PyYAML skips the mark


def test_a_folder_is_named_as_a_folder(tmp_path, model_path, capsys):
    code, err = _into(model_path, "kalibr", tmp_path, capsys)
    assert code == 2 and err.count("\n") == 1
    assert f"--into {tmp_path} is a folder" in err and f"--into {tmp_path / 'imu.yaml'}" in err
    assert "no such file" not in err


@pytest.mark.parametrize(("fmt", "text"), [
    ("kalibr", "{accelerometer_noise_density: 1.0e-3, accelerometer_random_walk: 1.0e-4, rostopic: /imu0}\n"),
    ("fast-lio", "{mapping: {acc_cov: 0.1, gyr_cov: 0.1, b_acc_cov: 0.0001, b_gyr_cov: 0.0001}}\n"),
    ("lio-sam", "lio_sam: {imuAccNoise: 0.01, imuGyrNoise: 0.001}\n"),
])  # fmt: skip
def test_flow_style_is_named(tmp_path, model_path, capsys, fmt, text):
    path = tmp_path / "flow.yaml"
    path.write_text(text)
    code, err = _into(model_path, fmt, path, capsys)
    assert code == 2 and err.count("\n") == 1 and f"--into {path}" in err
    assert "flow style" in err and "one 'key: value' per line" in err and "not a Kalibr" not in err
    assert path.read_text() == text and not list(tmp_path.glob("*.bak*"))


def test_a_folder_it_cannot_write_in(tmp_path, model_path, capsys, monkeypatch):
    """The backup and the new file go beside the file; a read-only folder is one line naming the folder, not the
    hidden temporary file the write failed on."""
    folder = tmp_path / "rig"
    folder.mkdir()
    path = folder / "imu.yaml"
    shutil.copyfile(FIX / "kalibr_imu.yaml", path)
    before = path.read_bytes()
    if os.geteuid() == 0:  # root writes through 0o555: make the write fail the way the OS fails it for a user
        import imunoise.io.tool_settings as ts

        def refuse(p, data):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(Path(p).parent / f".{Path(p).name}.x"))

        monkeypatch.setattr(ts, "atomic_write_bytes", refuse)
    folder.chmod(0o555)
    try:
        code, err = _into(model_path, "kalibr", path, capsys)
    finally:
        folder.chmod(0o755)
    assert code == 2 and err.count("\n") == 1
    assert f"--into {path}: cannot write in its folder" in err and "Permission denied" in err
    assert "make the folder writable" in err and "/." not in err  # no hidden temporary name
    assert path.read_bytes() == before and not list(folder.glob("*.bak*"))
