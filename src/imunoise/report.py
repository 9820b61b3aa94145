"""Self-contained reports: one HTML page (figures embedded) plus the same content as Markdown.

A report is a list of blocks (headings, paragraphs, tables, preformatted text, figures). Figures are
PNG files; the HTML embeds them as base64 so the page can be mailed or archived on its own, and the
Markdown links them relative to the report folder.
"""

from __future__ import annotations

import base64
import html
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Report", "fmt", "nobreak_numbers"]

# a number (sign, decimals, exponent), optionally joined to more by a range dash or slash ("21–32",
# "0.0188/0.0143/0.0138"); not inside a word or an HTML entity such as &#x27;
_NUMBER = r"[-−+]?\d+(?:\.\d+)?(?:[eE][-+−]?\d+)?%?"
_NUMBERS = re.compile(rf"(?<![\w.#&;]){_NUMBER}(?:\s?[–/]\s?{_NUMBER})*(?:\s(?:s|ms|m|Hz)\b)?")


_UNIT = re.compile(r"\[[^\]\s<>]{1,16}\]")  # a bracketed unit: "[u/√Hz]", "[(rad/s)²]"
_MODEL = re.compile(r"[\w*]+(?: \+ [\w*]+)+")  # a model structure: "2*AR1 + WN + RW"


def nobreak_numbers(escaped: str) -> str:
    """Wrap every number of already HTML-escaped text in a no-wrap span, so a line never breaks inside
    a number ("1.5e-05" after its "-", "21–32" at the dash), between a number and its unit (" s") or
    inside a bracketed unit ("[u/√Hz]")."""
    out = _NUMBERS.sub(lambda m: f"<span class='n'>{m.group(0)}</span>", escaped)
    return _UNIT.sub(lambda m: f"<span class='n'>{m.group(0)}</span>", out)


def fmt(value: Any, digits: int = 4) -> str:
    """Compact number formatting for tables (strings pass through)."""
    if isinstance(value, str):
        return value
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if v != v:
        return "–"
    if v == 0 or 1e-3 <= abs(v) < 1e5:
        return f"{v:.{digits}g}" if abs(v) < 1 else f"{v:.{max(digits - 1, 1)}f}".rstrip("0").rstrip(".")
    return f"{v:.{digits - 1}e}"


@dataclass
class Report:
    title: str
    blocks: list[tuple[str, Any]] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> Report:
        self.blocks.append(("heading", (level, text)))
        return self

    def paragraph(self, text: str) -> Report:
        self.blocks.append(("paragraph", text))
        return self

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[Any]], caption: str = "") -> Report:
        self.blocks.append(("table", (list(headers), [[fmt(c) for c in r] for r in rows], caption)))
        return self

    def pre(self, text: str) -> Report:
        self.blocks.append(("pre", text))
        return self

    def log(self, lines: Sequence[str]) -> Report:
        """Log lines (e.g. JSON events): monospace, each wrapped at spaces with a hanging indent."""
        self.blocks.append(("log", list(lines)))
        return self

    def figure(self, path: str | Path, caption: str = "") -> Report:
        self.blocks.append(("figure", (Path(path), caption)))
        return self

    # -- writers -------------------------------------------------------------------------------------
    def markdown(self, base: Path | None = None) -> str:
        out = [f"# {self.title}", ""]
        for element, payload in self.blocks:
            if element == "heading":
                level, text = payload
                out += ["#" * level + " " + text, ""]
            elif element == "paragraph":
                out += [payload, ""]
            elif element == "table":
                headers, rows, caption = payload
                if caption:
                    out += [f"*{caption}*", ""]
                out.append("| " + " | ".join(headers) + " |")
                out.append("|" + "---|" * len(headers))
                out += ["| " + " | ".join(r) + " |" for r in rows]
                out.append("")
            elif element == "pre":
                out += ["```", payload.rstrip(), "```", ""]
            elif element == "log":
                out += ["```", *payload, "```", ""]
            elif element == "figure":
                path, caption = payload
                rel = path.name if base is None else _relative(path, base)
                out += [f"![{caption}]({rel})", ""]
                if caption:
                    out += [f"*{caption}*", ""]
        return "\n".join(out)

    def html(self) -> str:
        parts = [
            "<!doctype html><html><head><meta charset='utf-8'>",
            f"<title>{html.escape(self.title)}</title>",
            "<style>body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;"
            "color:#222}table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;"
            "padding:3px 8px;text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}"
            "td:first-child,th:first-child{text-align:left}pre{background:#f7f7f7;padding:0.7em;"
            "overflow-x:auto;font-size:12px}img{max-width:100%;border:1px solid #ddd}"
            "figcaption{color:#555;font-size:90%;margin-bottom:1.5em}.meta{color:#777;font-size:85%}"
            # numbers never break (.n), numeric cells never wrap; log lines wrap at spaces only, with a
            # hanging indent so each event stays recognisable
            ".n,td.num{white-space:nowrap}caption{caption-side:top;text-align:left;color:#555}"
            ".log{background:#f7f7f7;padding:0.7em;font:12px ui-monospace,monospace}"
            ".log div{white-space:pre-wrap;overflow-wrap:normal;padding-left:3em;text-indent:-3em}</style>",
            "</head><body>",
            f"<h1>{html.escape(self.title)}</h1>",
            f"<p class='meta'>generated {time.strftime('%Y-%m-%d %H:%M:%S')} by imunoise</p>",
        ]
        for element, payload in self.blocks:
            if element == "heading":
                level, text = payload
                parts.append(f"<h{level}>{html.escape(text)}</h{level}>")
            elif element == "paragraph":
                parts.append(f"<p>{nobreak_numbers(html.escape(payload))}</p>")
            elif element == "table":
                headers, rows, caption = payload
                cap = f"<caption>{nobreak_numbers(html.escape(caption))}</caption>" if caption else ""
                head = "".join(f"<th>{nobreak_numbers(html.escape(h))}</th>" for h in headers)
                body = "".join("<tr>" + "".join(_cell(c) for c in r) + "</tr>" for r in rows)
                parts.append(f"<table>{cap}<tr>{head}</tr>{body}</table>")
            elif element == "pre":
                parts.append(f"<pre>{html.escape(payload)}</pre>")
            elif element == "log":
                lines = "".join(f"<div>{nobreak_numbers(html.escape(line))}</div>" for line in payload)
                parts.append(f"<div class='log'>{lines}</div>")
            elif element == "figure":
                path, caption = payload
                if path.exists():
                    data = base64.b64encode(path.read_bytes()).decode("ascii")
                    parts.append(
                        f"<figure><img src='data:image/png;base64,{data}' alt='{html.escape(caption)}'>"
                        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
                    )
                else:
                    parts.append(f"<p><em>missing figure {html.escape(str(path))}</em></p>")
        parts.append("</body></html>")
        return "\n".join(parts)

    def write(self, folder: str | Path, stem: str = "report") -> tuple[Path, Path]:
        """Write ``stem.html`` (self-contained) and ``stem.md`` into ``folder``."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        html_path = folder / f"{stem}.html"
        md_path = folder / f"{stem}.md"
        html_path.write_text(self.html())
        md_path.write_text(self.markdown(base=folder))
        return html_path, md_path


def _cell(text: str) -> str:
    """A table cell; one made only of numbers (with separators, brackets, signs) does not wrap at all."""
    esc = html.escape(text)
    # a list ("0.147, 0.139, …") may wrap at its commas: its numbers are no-break spans
    listy = "," in text and not text.startswith("[")
    if _MODEL.fullmatch(text):  # a model structure reads as one token
        return f"<td class='num'>{esc}</td>"
    if text and not listy and re.fullmatch(r"[\d\s.,eE+\-−–/\[\]%×]+", text) and any(ch.isdigit() for ch in text):
        return f"<td class='num'>{esc}</td>"
    return f"<td>{nobreak_numbers(esc)}</td>"


def _relative(path: Path, base: Path) -> str:
    try:
        return str(path.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(path)
