"""Every example of README.md runs as written (how: tests/doc_examples.py), and the slow tier of README and guide.

The README's tour repeats examples of the user guide word for word; such a block runs once, in
test_guide_examples.py, in the guide's order (which keeps what it reads from the examples before it). A README
block that is not in the guide runs here. The slow-tagged blocks of both run here, so that the guide's fast
examples and the slow tier spread over two workers.
"""

from __future__ import annotations

import re

import pytest

from conftest import REPO
from doc_examples import TEST_TIMEOUT_S, guide_blocks, parse_inputs, parse_markdown, parse_rst, run_all

README = REPO / "README.md"
BLOCKS = parse_markdown(README.read_text(encoding="utf-8"))
GUIDE_FAST = [b for b in guide_blocks() if b.tag == ""]


def _same(a, b) -> bool:
    return a.lang == b.lang and a.code.strip() == b.code.strip()


@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_readme_examples_run_here_or_in_the_guide(tmp_path):
    """README blocks found word for word among the guide's run there, in the README's order; the rest run here."""
    fast = [b for b in BLOCKS if b.tag == ""]
    assert fast, "the README has no example: the tags changed?"
    pos = [next((k for k, g in enumerate(GUIDE_FAST) if _same(b, g)), None) for b in fast]
    shared = [p for p in pos if p is not None]
    assert shared == sorted(shared), "README examples shared with the guide must keep the guide's order"
    own = [b for b, p in zip(fast, pos, strict=True) if p is None]
    if own:
        run_all(own, tmp_path)


@pytest.mark.slow
@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_slow_examples(tmp_path):
    """Blocks tagged slow in the README and the guide (each replays the real drive several times)."""
    run_all([b for b in BLOCKS + guide_blocks() if b.tag == "slow"], tmp_path)


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.tag in ("skip", "template")], ids=lambda b: f"line{b.line}")
def test_readme_skipped_blocks_are_reported(block):
    assert block.note, f"{block.label}: a skip tag or a template line needs a reason"
    pytest.skip(f"{block.label}: {block.tag}: {block.note}")


def test_readme_is_a_front_door():
    """At most 250 lines, and it starts with exactly the two commands a newcomer runs."""
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines: move the detail to the guide (docs/guide)"
    first = [b for b in BLOCKS][0]
    assert first.code == "make demo\nmake test\n" and first.line <= 3, first


def test_every_command_example_is_fenced():
    """An indented (unfenced) `imunoise` command would escape this test: there must be none."""
    in_fence = False
    for k, line in enumerate(README.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("```"):
            in_fence = not in_fence
        elif not in_fence and re.match(r"^ {4,}(\$ )?(imunoise|python|make) ", line):
            raise AssertionError(f"README.md:{k}: command outside a fenced block: {line.strip()}")


def test_parser_reads_tags_languages_and_templates():
    text = (
        "x\n<!-- readme-test: slow takes long -->\n```bash\nimunoise a\n```\n\n```python\nprint(1)\n```\n"
        "```yaml\nk: v\n```\n```\n# template: your log.csv\nimunoise b \\\n  c\n```\n"
    )
    got = parse_markdown(text)
    want = [(3, "shell", "slow"), (7, "python", ""), (13, "shell", "template")]
    assert [(b.line, b.lang, b.tag) for b in got] == want
    assert got[0].note == "takes long" and got[2].note == "your log.csv"
    assert got[2].code == "# template: your log.csv\nimunoise b \\\n  c\n"
    with pytest.raises(AssertionError, match="right before"):
        parse_markdown("<!-- readme-test: skip x -->\ntext\n```bash\nimunoise\n```\n")
    rst = (
        "Title\n=====\n\n.. readme-test: skip ten minutes\n\n.. code-block:: bash\n\n   imunoise a \\\n"
        "       --b\n\n   imunoise c\n\ntext\n\n.. code-block:: python\n   :caption: x\n\n   print(1)\n\n"
        ".. code-block:: yaml\n\n   k: v\n"
    )
    got = parse_rst(rst, "p.rst")
    assert [(b.line, b.lang, b.tag) for b in got] == [(6, "shell", "skip"), (15, "python", "")]
    assert got[0].code == "imunoise a \\\n    --b\n\nimunoise c\n" and got[1].code == "print(1)\n"
    with pytest.raises(AssertionError, match="literal block"):
        parse_rst("Run this::\n\n   imunoise a\n", "p.rst")
    with pytest.raises(AssertionError, match="start of a line"):
        parse_rst("- item\n\n  .. code-block:: bash\n\n     imunoise a\n", "p.rst")


def test_inputs_tag_copies_named_fixtures_before_the_block(tmp_path):
    """`readme-test: inputs DEST=SRC ...` runs the block like an untagged one, with the fixtures copied in."""
    md = ("<!-- readme-test: inputs EuRoC.yaml=tests/fixtures/orbslam3_euroc_v1.yaml "
          "rig/imu.yaml=tests/fixtures/kalibr_imu.yaml -->\n```bash\ncat EuRoC.yaml rig/imu.yaml > both.txt\n"
          "grep -c 'IMU.NoiseGyro' both.txt\ngrep -c accelerometer_noise_density both.txt\n```\n")
    (got,) = parse_markdown(md)
    assert (got.tag, got.line) == ("", 2)
    assert got.inputs == (("EuRoC.yaml", "tests/fixtures/orbslam3_euroc_v1.yaml"),
                          ("rig/imu.yaml", "tests/fixtures/kalibr_imu.yaml"))
    (rst,) = parse_rst(".. readme-test: inputs a.yaml=tests/fixtures/kalibr_imu.yaml\n\n.. code-block:: bash\n\n"
                       "   cat a.yaml\n", "p.rst")
    assert rst.tag == "" and rst.inputs == (("a.yaml", "tests/fixtures/kalibr_imu.yaml"),)
    run_all([got], tmp_path)  # fails unless both files were copied in
    for bad, why in (("a.yaml", "not DEST=SRC"), ("a.yaml=README.md", "under tests/fixtures/"),
                     ("../a.yaml=tests/fixtures/kalibr_imu.yaml", "inside the scratch root"),
                     ("/tmp/a.yaml=tests/fixtures/kalibr_imu.yaml", "inside the scratch root"),
                     ("a=tests/fixtures/../../README.md", "under tests/fixtures/"), ("", "at least one")):
        with pytest.raises(AssertionError, match=why):
            parse_inputs(bad)
    (tmp_path / "again").mkdir()
    with pytest.raises(AssertionError, match="no file tests/fixtures/absent.yaml"):
        run_all(parse_markdown("<!-- readme-test: inputs a=tests/fixtures/absent.yaml -->\n```bash\ntrue\n```\n"),
                tmp_path / "again")


def test_an_example_with_a_deprecated_option_fails(tmp_path):
    """The CLI keeps old option names with a notice on stderr; an example that still uses one fails."""
    md = "```bash\necho 'warning: --topic is deprecated; use --imu-topic (same meaning)' >&2\n```\n"
    with pytest.raises(AssertionError, match="uses deprecated option\\(s\\): --topic is deprecated; use --imu-topic"):
        run_all(parse_markdown(md), tmp_path)


# -- the fixes the README examples needed ------------------------------------------------------------------
def test_experiment_default_methods_pass_their_own_validation():
    """`imunoise experiment online --sim` used to fail on its own default list ('oracle')."""
    from imunoise.cli.experiment import select_methods
    from imunoise.errors import ImunoiseError
    from imunoise.experiments import denial, online_exp

    assert select_methods("online", True, None) == online_exp.MC_METHODS
    assert "oracle" in online_exp.MC_METHODS
    assert select_methods("online", False, None) == online_exp.METHODS
    assert select_methods("denial", True, None) == denial.METHODS
    assert select_methods("online", True, " plain, oracle ") == ("plain", "oracle")
    with pytest.raises(ImunoiseError, match=r"unknown method\(s\) \['oracle'\]"):
        select_methods("online", False, "plain,oracle")  # real data have no true model
    with pytest.raises(ImunoiseError, match="choose from"):
        select_methods("denial", True, "kalman")


def test_nav_model_accepts_a_one_axis_fit_and_the_simulator_truth(tmp_path):
    """`nav --model` with the model.json of `fit --column gyro_x`: that axis gets the fit, the rest the
    default; a fit of a column that names no axis is refused with what to do instead."""
    from imunoise.errors import ModelError
    from imunoise.nav.defaults import default_axis_models, load_axis_models

    fit = {
        "kind": "imunoise.fit",
        "model": "AR1 + WN",
        "params": {"AR1_1.phi": 0.999, "AR1_1.sigma2": 1e-8, "WN.sigma2": 1e-6},
        "freq_hz": 200.0,
        "unit": "rad/s",
        "extra": {"column": "gyro_y"},
    }
    default = default_axis_models(100.0)
    got = load_axis_models(fit, 100.0)
    assert str(got[1]) == "AR1 + WN" and got[1].freq == 200.0
    assert got[1].params == fit["params"]
    for a in (0, 2, 3, 4, 5):
        assert got[a].params == default[a].params and got[a].freq == 100.0
    with pytest.raises(ModelError, match=r"--columns gyro_x=COL.*imu_model\.json"):
        load_axis_models({**fit, "extra": {"column": "rate"}}, 100.0)
    truth = {"seed": 1, "models": {"gz": fit, "ax": {**fit, "unit": "m/s^2"}}}  # the layout of truth.json
    got = load_axis_models(truth, 100.0)
    assert str(got[2]) == "AR1 + WN" and str(got[3]) == "AR1 + WN"
    assert got[0].params == default[0].params
