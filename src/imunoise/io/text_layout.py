"""How a text table is laid out: column separator, decimal mark, header (docs/guide/theory.rst, 'Interfaces').

One function, :func:`text_layout`, read by the whole-file reader (:func:`imunoise.io.tabular.read_table`)
and the block reader (:mod:`imunoise.io.imu_stream`) on the first lines of a file, so both read a file the
same way. What it decides, and why:

* **Separator**: tab, ``;``, ``,`` or white space (``csv.Sniffer``), except that a ``;`` on every line
  wins: spreadsheets in locales with a decimal comma write ``1,5;2,3``, where the sniffer may take the
  comma for the separator and split every number in two.
* **Decimal comma**: with ``;`` (or tab) between the columns and commas inside the cells, every cell reads
  as a number once its comma is a point: the file is read that way (``1,5`` = 1.5).
* A comma-separated file whose "columns" are the halves of decimal-comma numbers (``0,0012`` read as 0
  and 12: fractional parts with leading zeros, ``-0`` integer parts) is refused: the separator and the
  decimal mark are the same character and nothing can tell them apart.
* **Header**: the first line is a header when one of its cells is not a number. A header naming fewer
  (or more) columns than the rows hold is refused: the names would slide onto the wrong columns.
* A UTF-8 byte-order mark (Excel's "CSV UTF-8") is not part of the first name.
"""

from __future__ import annotations

import csv
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from imunoise.errors import DataError
from imunoise.io.files import is_number

__all__ = ["TextLayout", "text_layout"]

_SAMPLE_LINES = 20
_BOM = "\ufeff"


@dataclass(frozen=True)
class TextLayout:
    """``delimiter`` (None = white space), ``decimal_comma``, ``has_header`` and the column ``names``."""

    delimiter: str | None
    decimal_comma: bool
    has_header: bool
    names: list[str]

    def split(self, line: str) -> list[str]:
        """The cells of one line (stripped), with a decimal comma turned into a point."""
        return [t.strip() for t in self.split_raw(self.normalise(line))]

    def split_raw(self, line: str) -> list[str]:
        return line.split(self.delimiter) if self.delimiter else line.split()

    def normalise(self, line: str) -> str:
        """``line`` as :func:`numpy.loadtxt` can read it with :attr:`delimiter` (decimal comma -> point)."""
        return line.replace(",", ".") if self.decimal_comma else line


def _sniff(sample: list[str]) -> str | None:
    text = "\n".join(sample)
    for d in ("\t", ";"):
        counts = {ln.count(d) for ln in sample}
        if len(counts) == 1 and counts != {0} and (d == ";" or "," in text):
            return d  # the same number of tabs/semicolons on every line: the separator, commas are decimals
    try:
        delim = csv.Sniffer().sniff(text, delimiters=",;\t ").delimiter
    except csv.Error:
        delim = ","
    if delim == " " or ("," not in text and ";" not in text and "\t" not in text):
        return None  # any white space
    return delim


def _halves_of_decimal_commas(cells: Sequence[Sequence[str]]) -> bool:
    """True when comma-split cells look like the two halves of decimal-comma numbers: every cell an integer,
    and in most lines a later cell with a leading zero (a fractional part, '0012') or a first cell '-0'."""
    if not cells or any(not all(c.lstrip("+-").isdigit() for c in row) for row in cells):
        return False
    hits = sum(
        1 for row in cells if row[0] == "-0" or any(len(c) > 1 and c.startswith("0") for c in row[1:])
    )
    return hits * 2 >= len(cells)


def text_layout(path: str | Path, content: Sequence[tuple[int, str]]) -> TextLayout:
    """The layout of a text table from its data lines ``content`` ((line number, line) pairs, comments and
    blank lines already removed): separator, decimal mark, header; module docstring for the rules.

    Raises :class:`DataError` naming the file for a header that names more or fewer columns than the rows
    hold, and for decimal commas in a comma-separated file.
    """
    if not content:
        raise DataError(f"{path} has no data lines")
    lines = [ln for _, ln in content]
    if lines[0].startswith(_BOM):
        lines[0] = lines[0][len(_BOM):]
    sample = lines[:_SAMPLE_LINES]
    delim = _sniff(sample)
    decimal_comma = False
    if delim in (";", "\t") and any("," in ln for ln in sample[1:] or sample):
        rows = [[c.strip() for c in ln.split(delim)] for ln in sample]
        data_rows = rows[1:] if not all(is_number(c) for c in rows[0] if c) else rows
        decimal_comma = bool(data_rows) and all(is_number(c.replace(",", ".")) for r in data_rows for c in r if c)
    layout = TextLayout(delim, decimal_comma, False, [])
    first = layout.split(lines[0])
    has_header = not all(is_number(t) for t in first if t != "")
    data = sample[1:] if has_header else sample
    if delim == "," and _halves_of_decimal_commas([layout.split(ln) for ln in data]):
        example = data[0].strip()
        raise DataError(
            f"{path}, line {content[1 if has_header else 0][0]}: {example!r} looks like numbers written with a "
            "decimal comma, which is also the column separator here; save the file with decimal points "
            "(or with ';' between the columns)"
        )
    if has_header and data:
        _check_header(path, content[0][0], first, [layout.split(ln) for ln in data], layout.split)
    names = first if has_header else [str(i) for i in range(len(first))]
    return TextLayout(delim, decimal_comma, has_header, names)


def _check_header(path: str | Path, lineno: int, header: list[str], rows: list[list[str]],
                  split: Callable[[str], list[str]]) -> None:
    """Refuse a header whose name count differs from the field count of the rows (the most common one of
    the first lines: a cut first line is the reader's business)."""
    usual, _ = Counter(len(r) for r in rows).most_common(1)[0]
    if usual == len(header):
        return
    names = ", ".join(header)
    if usual > len(header):
        k = usual - len(header)
        raise DataError(
            f"{path}, line {lineno}: the header names {len(header)} columns ({names}) but the rows have {usual} "
            f"fields: {k} column{'s have' if k > 1 else ' has'} no name; add the missing name{'s' if k > 1 else ''} "
            "to the header (or remove the unnamed column)"
        )
    raise DataError(
        f"{path}, line {lineno}: the header names {len(header)} columns ({names}) but the rows have only {usual} "
        "fields; fix the header or the separator"
    )
