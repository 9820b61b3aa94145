"""The sample rate a model's parameters refer to (docs/guide/theory.rst, 'Conventions': parameters are per sample
at the rate of the data they describe): checking a rate, and choosing between a model's own rate and one a caller
passes. :class:`imunoise.noise.model.Model` carries the rate as ``freq``; this module holds the rules so every
form that needs a rate (continuous values, state space, rate change, the filter) applies the same ones.
"""

from __future__ import annotations

import math
import numbers

from imunoise.errors import ModelError

__all__ = ["checked_freq", "resolve_rate"]


def checked_freq(freq: float | None) -> float | None:
    """``freq`` as a float [Hz], None kept; anything that is not a finite number > 0 is refused (ModelError)."""
    if freq is None:
        return None
    if isinstance(freq, bool) or not isinstance(freq, numbers.Real):  # "100" or True are not guessed
        raise ModelError(f"a sample rate is a number of Hz > 0, got {freq!r}; e.g. model.with_freq(100.0)")
    f = float(freq)
    if not (f > 0 and math.isfinite(f)):
        raise ModelError(f"a sample rate must be a finite number of Hz > 0, got {freq!r}")
    return f


def resolve_rate(model: object, own: float | None, given: float | None, what: str) -> float:
    """The rate [Hz] of ``model`` (its ``own``, or ``given`` when it has none) for the form ``what`` needs.

    Raises
    ------
    ModelError
        When neither is known (the message names the fix: fit with ``freq=`` or ``model.with_freq(rate_hz)``),
        or when ``given`` contradicts the model's own rate (the fix: leave it out, or ``at_rate``).
    """
    g = checked_freq(given)
    if own is None:
        if g is None:
            raise ModelError(
                f"model {model} carries no sample rate and {what} needs one: fit it with freq=..., or state it "
                "with model.with_freq(rate_hz) (its parameters are per sample at that rate)"
            )
        return g
    if g is not None and g != own:
        raise ModelError(
            f"model {model} has parameters per sample at {own:g} Hz, not {g:g} Hz: leave the rate out, or "
            f"convert the model with model.at_rate({own:g}, {g:g})"
        )
    return own
