"""A report as a list of blocks, rendered two ways with the same content: one self-contained HTML
page (figures embedded as PNG data, nothing fetched) for a browser, and Markdown with the figures
as PNG files beside it for a ticket or a wiki.

Text is a string, or a list of strings and :class:`Strong` runs; every string is escaped for the
format it goes to.
"""

from __future__ import annotations

import base64
import html
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .outputs import write_text

CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:1.5em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left}
th{background:#f2f2f2}td.n{text-align:right}img{max-width:100%;margin:.4em 0}
.ok{background:#e3f4e3;border:1px solid #7c7;padding:.6em 1em}.failed{background:#fbe3e3;border:1px solid #d77;
padding:.6em 1em}.partial{background:#fff5d6;border:1px solid #db5;padding:.6em 1em}
.note{color:#555;font-size:.92em}h2{border-bottom:2px solid #ddd;margin-top:1.6em}"""

#: paragraph styles: a box in HTML (the verdict, the status), a quote in Markdown; or a note in grey
BOXES = ("ok", "partial", "failed")
STYLES = (*BOXES, "note")
#: what a report without figures says under its title
FIGURES_LEFT_OUT = "Figures not drawn (--no-figures): the numbers are all here, the plots are not."


@dataclass(frozen=True)
class Strong:
    """Bold text in a run of text.

    Parameters
    ----------
    text : str
        The text.
    """

    text: str


#: a run of text: plain, bold (Strong), or several in a row
Text = str | Strong | Sequence[str | Strong]

_NUMBER = re.compile(r"^[+\-]?(\d[\d.,]*(e[+\-]?\d+)?|–)( ?(%|×|→ ?\S+))?$")


def _numeric(text: object) -> bool:
    """A cell that holds a number (right-aligned in HTML, as numbers are read)."""
    return isinstance(text, str) and bool(_NUMBER.match(text.strip()))


def number(value: object, fmt: str = ".6g") -> str:
    """A number for a table or a sentence: a float in ``fmt`` (a REAL32 read back as
    0.11999999731779099 is 0.12), anything else (a whole number, a name) as it is, "–" where
    there is none.

    Parameters
    ----------
    value : object
        The value.
    fmt : str
        The format of a float.

    Returns
    -------
    str
        The text.
    """
    if value is None:
        return "–"
    return format(value, fmt) if isinstance(value, (float, np.floating)) else str(value)


def measured(value: float, std: float | None) -> str:
    """``value`` with the digits its ``std`` supports: the last one at the std's second significant
    digit (2 to 7 significant digits); 6 where there is no std.

    Parameters
    ----------
    value : float
        The value.
    std : float or None
        Its std.

    Returns
    -------
    str
        The value's text.
    """
    if std is None or not np.isfinite(std) or not std > 0 or not value or not np.isfinite(value):
        return f"{value:.6g}"
    digits = int(np.floor(np.log10(abs(value))) - np.floor(np.log10(std))) + 2
    return f"{value:.{min(7, max(2, digits))}g}"


def _runs(text: Text) -> list:
    return [text] if isinstance(text, (str, Strong)) else list(text)


def _html(text: Text) -> str:
    return "".join(
        f"<b>{html.escape(r.text)}</b>" if isinstance(r, Strong) else html.escape(str(r)) for r in _runs(text)
    )


def _md(text: Text, cell: bool = False) -> str:
    out = []
    for r in _runs(text):
        s = r.text if isinstance(r, Strong) else str(r)
        if cell:
            s = s.replace("|", "\\|").replace("\n", " ")
        out.append(f"**{s}**" if isinstance(r, Strong) and s else s)
    return "".join(out)


@dataclass
class Document:
    """Blocks in reading order; ``html()`` and ``markdown()`` render them.  Without ``figures``
    (``--no-figures``) it holds none, whatever files a run directory still has from an earlier run,
    and says so under its title.

    Parameters
    ----------
    title : str
        The title.
    blocks : list of tuple
        The blocks, in reading order (as the methods below add them).
    figures : bool
        Figures are shown (``--no-figures``: none).
    """

    title: str
    blocks: list[tuple] = field(default_factory=list)
    figures: bool = True

    def __post_init__(self) -> None:
        if not self.figures:
            self.para(FIGURES_LEFT_OUT, "note")

    def heading(self, level: int, text: Text) -> None:
        """A heading.

        Parameters
        ----------
        level : int
            1 under the title, 2 under that, ...
        text : str, Strong or sequence of them
            Its text.
        """
        self.blocks.append(("h", level, text))

    def para(self, text: Text, style: str | None = None) -> None:
        """A paragraph.

        Parameters
        ----------
        text : str, Strong or sequence of them
            Its text.
        style : str, optional
            One of :data:`STYLES` (a verdict's colour, a note).

        Raises
        ------
        ValueError
            Another style.
        """
        if style is not None and style not in STYLES:
            raise ValueError(f"style must be one of {STYLES}")
        self.blocks.append(("p", text, style))

    def bullets(self, items: list) -> None:
        """A bulleted list (nothing where it is empty).

        Parameters
        ----------
        items : list
            Its items (text).
        """
        if items:
            self.blocks.append(("ul", items))

    def table(self, head: list, rows: list[list]) -> None:
        """A table (numbers right-aligned in HTML).

        Parameters
        ----------
        head : list
            The column heads.
        rows : list of list
            The rows' cells (text).
        """
        self.blocks.append(("table", head, rows))

    def figure(self, path: str | Path, alt: str) -> None:
        """A PNG file (left out where it was not made, or the document has no figures).

        Parameters
        ----------
        path : str or Path
            The PNG.
        alt : str
            What it shows, in words.
        """
        if self.figures and Path(path).is_file():
            self.blocks.append(("img", Path(path), alt))

    # ---------------------------------------------------------------- rendering
    def html(self) -> str:
        """The document as one self-contained HTML page (figures embedded).

        Returns
        -------
        str
            The page.
        """
        body = [f"<h1>{html.escape(self.title)}</h1>"]
        for kind, *b in self.blocks:
            if kind == "h":
                body.append(f"<h{b[0] + 1}>{_html(b[1])}</h{b[0] + 1}>")
            elif kind == "p":
                tag = "div" if b[1] in BOXES else "p"
                cls = f" class='{b[1]}'" if b[1] else ""
                body.append(f"<{tag}{cls}>{_html(b[0])}</{tag}>")
            elif kind == "ul":
                body.append("<ul>" + "".join(f"<li>{_html(i)}</li>" for i in b[0]) + "</ul>")
            elif kind == "table":
                head = "".join(f"<th>{_html(c)}</th>" for c in b[0])
                rows = "".join(
                    "<tr>"
                    + "".join(f"<td{' class=n' if _numeric(c) else ''}>{_html(c)}</td>" for c in r)
                    + "</tr>"
                    for r in b[1]
                )
                body.append(f"<table><tr>{head}</tr>{rows}</table>")
            else:
                data = base64.b64encode(b[0].read_bytes()).decode()
                body.append(f'<img alt="{html.escape(b[1])}" src="data:image/png;base64,{data}">')
        return (
            f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>"
            f"<style>{CSS}</style></head><body>{''.join(body)}</body></html>"
        )

    def markdown(self, where: Path) -> str:
        """Markdown for a file in the directory ``where``: figures linked by their path from there.

        Parameters
        ----------
        where : Path
            The Markdown file's directory.

        Returns
        -------
        str
            The Markdown.
        """
        md = [f"# {self.title}", ""]
        for kind, *b in self.blocks:
            if kind == "h":
                md += [f"{'#' * (b[0] + 1)} {_md(b[1])}", ""]
            elif kind == "p":
                text = _md(b[0])
                md += [f"> {text}" if b[1] in BOXES else f"*{text}*" if b[1] == "note" else text, ""]
            elif kind == "ul":
                md += [f"- {_md(i)}" for i in b[0]] + [""]
            elif kind == "table":
                md += [
                    "| " + " | ".join(_md(c, True) for c in b[0]) + " |",
                    "|" + "|".join(" --- " for _ in b[0]) + "|",
                ]
                md += ["| " + " | ".join(_md(c, True) for c in r) + " |" for r in b[1]] + [""]
            else:
                md += [f"![{b[1]}]({Path(os.path.relpath(b[0], where)).as_posix()})", ""]
        return "\n".join(md)

    def write(self, html_path: str | Path, md_path: str | Path) -> tuple[Path, Path]:
        """Both renderings; the Markdown's figures are the files the document names.

        Parameters
        ----------
        html_path : str or Path
            The HTML file to write.
        md_path : str or Path
            The Markdown file to write.

        Returns
        -------
        (Path, Path)
            The two files.
        """
        write_text(html_path, self.html())
        return Path(html_path), write_text(md_path, self.markdown(Path(md_path).parent))
