"""Research-only options are marked as such where a user meets them: the --help text and the run's warnings."""

from __future__ import annotations

from imunoise.cli import build_parser
from imunoise.cli import online as online_cli


def _option_help(command: str, flag: str) -> str:
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    return next(a.help for a in sub.choices[command]._actions if flag in a.option_strings)


def test_the_likelihood_statistic_is_marked_experimental_in_help_and_warning():
    text = _option_help("online", "--motion-noise-statistic")
    assert "EXPERIMENTAL" in text and "drift" in text
    # the warning a run logs and records in metrics.json names the option, says why and where the record is
    w = online_cli.EXPERIMENTAL_LIKELIHOOD
    assert "--motion-noise-statistic likelihood" in w and "experimental" in w
    assert "docs/evidence/in_motion_likelihood.md" in w
