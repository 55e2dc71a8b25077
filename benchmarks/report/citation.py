"""What to cite for a report: the closing ``Cite:`` lines of every report.

The one place of the bibliographic data of the papers whose tables the project reproduces
(:data:`PAPERS`, taken from the papers themselves), of which configuration or study reproduces
which of their tables (:data:`REPRODUCES`) and of which paper each published results table
(``systems/data/paper_tables/<key>.yaml``) comes from (:data:`TABLE_PAPERS`).  Every report
ends with (Markdown: just before its provenance comment, if it has one)::

    Cite: <authors>, "<title>", <venue>, <year> (the table reproduced: Table 3);
    setobs-bench <version> (CITATION.cff).

one line per paper (the one whose table the report reproduces, then those whose published
values the report shows beside ours) and the project's line last, with the version of the
installed package; a report that reproduces no table and shows no published value cites the
project alone.

>>> lines = citation_lines("arch2021_table3")
>>> lines[0].startswith('Cite: M. Althoff, "Guaranteed State Estimation in CORA 2021"')
True
>>> lines[0].endswith("(the table reproduced: Table 3);")
True
>>> citation_lines("mhe")[0].startswith("Cite: setobs-bench ")
True
"""

from __future__ import annotations

import html
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import metadata

#: the distribution whose version the project line carries
PROJECT = "setobs-bench"
#: where the project's own citation data are (the repository root)
CITATION_FILE = "CITATION.cff"


@dataclass(frozen=True)
class Paper:
    """Bibliographic data of one paper.

    Parameters
    ----------
    authors : str
        Authors as printed (initials and surnames).
    title : str
        Title, capitalised as in the paper.
    venue : str
        Journal (with volume and article number) or conference.
    year : int
        Year of publication.
    """

    authors: str
    title: str
    venue: str
    year: int

    def text(self) -> str:
        """``<authors>, "<title>", <venue>, <year>``."""
        return f'{self.authors}, "{self.title}", {self.venue}, {self.year}'


#: the papers, by key (data from the papers' texts: title pages and the CORA 2021 paper's
#: reference to Althoff & Rath)
PAPERS = {
    "althoff-rath-2021": Paper(
        "M. Althoff and J. J. Rath",
        "Comparison of Guaranteed State Estimators for Linear Time-Invariant Systems",
        "Automatica 130, article no. 109662", 2021),
    "althoff-2021": Paper(
        "M. Althoff", "Guaranteed State Estimation in CORA 2021",
        "Workshop on Applied Verification for Continuous and Hybrid Systems (ARCH)", 2021),
    "alanwar-2022": Paper(
        "A. Alanwar, A. Berndt, K. H. Johansson and H. Sandberg",
        "Data-Driven Set-Based Estimation using Matrix Zonotopes with Set Containment "
        "Guarantees", "European Control Conference (ECC)", 2022),
    "ctms-1999": Paper(
        "W. C. Messner and D. M. Tilbury",
        "Control Tutorials for MATLAB and Simulink: A Web-Based Approach",
        "Addison-Wesley (web edition: Control Tutorials for MATLAB and Simulink, CTMS)", 1999),
}

#: report (shipped configuration or study) -> the paper it reproduces and what of it
REPRODUCES = {
    "arch2021_table3": ("althoff-2021", "the table reproduced: Table 3"),
    "arch2021_table4": ("althoff-2021", "the table reproduced: Table 4"),
    "arch2021_table5": ("althoff-2021", "the table reproduced: Table 5"),
    "arch2021_table6": ("althoff-2021", "the table reproduced: Table 6"),
    "arch2021_table6_12tanks": ("althoff-2021", "the table reproduced: Table 6, 12 tanks"),
    "automatica2021_table3": ("althoff-rath-2021", "the table reproduced: Table 3"),
    "alanwar2022": ("alanwar-2022", "the evaluation reproduced: Sec. IV"),
    "datadriven": ("alanwar-2022", "the evaluation reproduced: Sec. IV"),
    "textbook": ("ctms-1999", "the plants' models and parameters"),
}

#: published results table (``systems/data/paper_tables/<key>.yaml``) -> its paper
TABLE_PAPERS = {
    "arch2021_table3_tank6_linear": "althoff-2021",
    "arch2021_table4_tank6_nonlinear": "althoff-2021",
    "arch2021_table5_6_tank_scaling": "althoff-2021",
    "automatica2021_table3_vehicle6": "althoff-rath-2021",
    "alanwar2022_datadriven": "alanwar-2022",
}

#: what a paper cited for its published values (not a reproduced table) is cited for
SHOWN = "published values shown beside ours"


def project_version() -> str:
    """Version of the installed package, e.g. ``"0.2.0"`` (``"unknown"`` if it is not
    installed): the one lookup of the version (reports, ``--version``, the golden files)."""
    try:
        return metadata.version(PROJECT)
    except metadata.PackageNotFoundError:
        return "unknown"


def project_line() -> str:
    """``setobs-bench <version> (CITATION.cff)``."""
    return f"{PROJECT} {project_version()} ({CITATION_FILE})"


def cited(report: str | None, tables: Iterable[str | None] = ()) -> list[tuple[Paper, str]]:
    """The papers a report cites and what for: the one ``report`` reproduces, then those of
    the published ``tables`` it shows (keys of :data:`TABLE_PAPERS`; others are ignored),
    each paper once.

    Parameters
    ----------
    report : str or None
        Name of the configuration or study (:data:`REPRODUCES`).
    tables : iterable of str or None
        Keys of the published tables whose values the report shows.

    Returns
    -------
    list of (Paper, str)
        Each paper with what it is cited for.
    """
    out: dict[str, str] = {}
    if report in REPRODUCES:
        key, what = REPRODUCES[report]
        out[key] = what
    for table in tables:
        key = TABLE_PAPERS.get(table or "")
        if key is not None and key not in out:
            out[key] = SHOWN
    return [(PAPERS[key], what) for key, what in out.items()]


def citation_lines(report: str | None, tables: Iterable[str | None] = ()) -> list[str]:
    """The ``Cite:`` lines of a report (Markdown; one paragraph): a line per paper
    (:func:`cited`), then the project's line with the installed version.

    Parameters
    ----------
    report : str or None
        Name of the configuration or study.
    tables : iterable of str or None
        Keys of the published tables whose values the report shows.

    Returns
    -------
    list of str
        The lines, without a blank line around them.
    """
    lines = [f"{paper.text()} ({what});" for paper, what in cited(report, tables)]
    lines.append(project_line() + ".")
    lines[0] = "Cite: " + lines[0]
    return lines


def citation_html(report: str | None, tables: Iterable[str | None] = ()) -> str:
    """The ``Cite:`` lines of :func:`citation_lines` as an HTML paragraph."""
    return ('<p class="cite">' + "<br>".join(html.escape(line)
                                              for line in citation_lines(report, tables))
            + "</p>")

