"""One meaning per option name across commands (issue 22, "What a new user meets first: Options"; acceptance 5).

The real parser is built and every sub-parser walked; each long option used by more than one command is listed
with its help text, and its meaning compared: the same ``dest``, action kind, ``nargs``, value type and choices,
the same subject in the help, and the same number default. The help convention the comparison reads:
``[CONTEXT: ]SUBJECT[ (details)][; more]`` — an optional context naming where the option applies (a help starting
"simulator: " is about the simulated drive), then the subject, which is what the option *is*, cut at the first
" (", ";", ": " or ", e.g.". Folder and file are the same kind of value (a path). A number default may differ only
under a context. Hidden former names (:class:`imunoise.cli.options.DeprecatedAlias`) are not part of the
vocabulary: each must point to a visible option of its command and warn when used.
"""

from __future__ import annotations

import argparse
import re
from collections import defaultdict
from typing import NamedTuple

import pytest

from imunoise.cli import build_parser, main
from imunoise.cli.options import DeprecatedAlias

CONTEXTS = (
    "simulator",
    "ros bag",
    "table",
    "real data",
    "online methods",
    "static demo",
    "online demo",
    "denial --sim",
    "--export",
    "demo data",
)
"""Where an option applies, written as a help's first words ("simulator: ..."): a vocabulary of places, not of
option names."""

_CUT = re.compile(r":\s|;|\s\(|, e\.g\.")


class Use(NamedTuple):
    command: str
    dest: str
    kind: str
    nargs: object
    type: str
    choices: tuple | None
    context: str
    subject: str
    default: object
    help: str


def split_help(text: str | None) -> tuple[str, str]:
    """(context, subject) of a help text (module docstring)."""
    h = (text or "").strip().lower()
    context = ""
    for c in CONTEXTS:
        if h.startswith(c + ": "):
            context, h = c, h[len(c) + 2 :]
            break
    subject = _CUT.split(h, maxsplit=1)[0].strip()
    return context, re.sub(r"\b(file|folder)\b", "path", subject)


def _type_name(t: object) -> str:
    name = getattr(t, "__name__", "") if t is not None else "str"
    if name in ("str", "Path", ""):
        return "text"
    return "number" if "float" in name else "whole number" if "int" in name else name


def _commands(parser: argparse.ArgumentParser, prefix: str = ""):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                yield f"{prefix}{name}", sp
                yield from _commands(sp, f"{prefix}{name} ")


def vocabulary(parser: argparse.ArgumentParser) -> tuple[dict[str, list[Use]], list[tuple[str, str, DeprecatedAlias]]]:
    """Every visible long option → its uses, and the hidden former names (command, name, action)."""
    uses: dict[str, list[Use]] = defaultdict(list)
    aliases = []
    for cmd, sp in _commands(parser):
        for a in sp._actions:
            longs = [o for o in a.option_strings if o.startswith("--") and o != "--help"]
            if isinstance(a, DeprecatedAlias):
                aliases += [(cmd, o, a) for o in longs]
                continue
            if a.help == argparse.SUPPRESS:
                continue
            context, subject = split_help(a.help)
            for o in longs:
                uses[o].append(
                    Use(cmd, a.dest, type(a).__name__, a.nargs, _type_name(a.type),
                        tuple(a.choices) if a.choices is not None else None, context, subject, a.default,
                        a.help or "")  # fmt: skip
                )
    return uses, aliases


def conflicts(uses: list[Use]) -> list[str]:
    """What makes the uses of one option name differ in meaning (empty: one meaning)."""
    out = []
    for field in ("dest", "kind", "nargs", "type", "choices"):
        values = {getattr(u, field) for u in uses}
        if len(values) > 1:
            out.append(f"{field} differs: " + ", ".join(f"{u.command}={getattr(u, field)!r}" for u in uses))
    described = [u for u in uses if u.help]
    if len({u.subject for u in described}) > 1:
        out.append("help subject differs: " + "; ".join(f"{u.command}: {u.subject!r}" for u in described))
    numbers = [
        u for u in uses if not u.context and isinstance(u.default, (int, float)) and not isinstance(u.default, bool)
    ]
    if len({u.default for u in numbers}) > 1:
        out.append("default differs: " + ", ".join(f"{u.command}={u.default!r}" for u in numbers))
    return out


PARSER = build_parser()
USES, ALIASES = vocabulary(PARSER)
SHARED = sorted(name for name, u in USES.items() if len({x.command for x in u}) > 1)


def listing() -> str:
    lines = []
    for name in SHARED:
        lines.append(name)
        lines += [f"    {u.command:<11} {u.help or '(no help)'}" for u in USES[name]]
    return "\n".join(lines)


def test_listing_of_shared_names(capsys):
    """The table the issue asks for: every shared name with the help of each command using it."""
    text = listing()
    with capsys.disabled():
        print(f"\n{len(SHARED)} option names shared by several commands:\n{text}")
    assert {"--out", "--imu", "--gnss", "--imu-topic", "--imu-model", "--stops", "--lever-arm", "--yaw"} <= set(SHARED)
    for name in SHARED:
        assert f"\n{name}\n" in f"\n{text}\n"


@pytest.mark.parametrize("name", SHARED)
def test_shared_name_has_one_meaning(name):
    problems = conflicts(USES[name])
    assert not problems, f"{name}: " + " | ".join(problems)


def test_the_check_sees_the_old_conflicts():
    """The comparison is not always true: the definitions of the issue's report are caught."""
    p = argparse.ArgumentParser()
    sub = p.add_subparsers()
    nav, online, exp, sim = (sub.add_parser(n) for n in ("nav", "online", "experiment", "simulate"))
    nav.add_argument("--no-gate", action="store_true", help="disable the χ² innovation gate")
    online.add_argument("--no-gate", action="store_true", help="do not use the 30 °/s angular-rate gate")
    nav.add_argument("--imu", help="IMU: KF-GINS increments or rate CSV (SI), or a ROS bag")
    exp.add_argument("--imu", help="simulator: IMU error models: preset (paper, mems, tactical), structure")
    nav.add_argument("--gnss", help="GNSS file: KF-GINS text, an RTKLIB .pos solution, or a ROS bag")
    exp.add_argument("--gnss", action="append", help="GNSS regime, repeatable: rtk or noise:H,V")
    sim.add_argument("--stops", type=int, default=3, help="traffic-light stops during the drive (default 3)")
    exp.add_argument("--stops", type=int, default=4, help="traffic-light stops during the drive (default 4)")
    old, _ = vocabulary(p)
    assert "help subject differs" in " ".join(conflicts(old["--no-gate"]))
    assert "help subject differs" in " ".join(conflicts(old["--imu"]))
    assert "kind differs" in " ".join(conflicts(old["--gnss"]))
    assert conflicts(old["--stops"]) == ["default differs: experiment=4, simulate=3"]


@pytest.mark.parametrize(("command", "old", "action"), ALIASES, ids=[f"{c} {o}" for c, o, _ in ALIASES])
def test_former_names_point_to_a_visible_option(command, old, action):
    sp = dict(_commands(PARSER))[command]
    new = [a for a in sp._actions if action.new in a.option_strings]
    assert len(new) == 1 and new[0].help != argparse.SUPPRESS and new[0].dest == action.dest


@pytest.mark.parametrize(
    ("argv", "old", "new", "dest", "value"),
    [
        (["fit", "x.csv", "--model", "WN"], "--topic", "--imu-topic", "topic", "/imu"),
        (["nav", "--out", "o"], "--no-gate", "--no-chi2-gate", "no_chi2_gate", True),
        (["online", "--out", "o"], "--no-gate", "--no-rate-gate", "no_rate_gate", True),
        (["nav", "--out", "o"], "--model", "--imu-model", "imu_model", "m.json"),
        (["experiment", "online", "--out", "o"], "--imu", "--imu-model", "imu_model", "mems"),
        (["experiment", "online", "--out", "o"], "--gnss", "--gnss-regime", "gnss_regime", ["rtk"]),
    ],
)
def test_former_names_still_work_and_warn(argv, old, new, dest, value, capsys):
    extra = [] if value is True else [value[0] if isinstance(value, list) else value]
    a_old = PARSER.parse_args([*argv, old, *extra])
    err = capsys.readouterr().err
    a_new = PARSER.parse_args([*argv, new, *extra])
    assert getattr(a_old, dest) == getattr(a_new, dest) == value
    assert f"warning: {old} is deprecated; use {new}" in err
    assert "deprecated" not in capsys.readouterr().err


def test_stops_default_is_the_same_in_simulate_and_experiment():
    sim = PARSER.parse_args(["simulate"])
    exp = PARSER.parse_args(["experiment", "online", "--sim", "--out", "o"])
    assert sim.stops == exp.stops == 4


def test_nav_and_online_start_at_the_manifest_start(tmp_path, capsys):
    """`nav` and `online` read the dataset's start_sow the same way: a start_sow outside the IMU data names
    the manifest in both."""
    import json
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2] / "data" / "drive_0708"
    man = json.loads((repo / "dataset.json").read_text())
    d = tmp_path / "ds"
    d.mkdir()
    for key in ("imu", "gnss"):
        (d / man[key]).symlink_to(repo / man[key])
    (d / "dataset.json").write_text(json.dumps({"imu": man["imu"], "gnss": man["gnss"], "start_sow": 1.0}))
    for cmd in ("nav", "online"):
        try:
            code = main([cmd, "--data", str(d), "--out", str(tmp_path / cmd)])
        except SystemExit as exc:  # pragma: no cover - a parse error would be a test bug
            code = int(exc.code or 0)
        err = capsys.readouterr().err
        assert code == 2, err
        assert "start_sow of" in err and "is outside the IMU data" in err
