"""Sphinx HTML math renderer ``mathml``: the LaTeX of ``.. math::`` and ``:math:`` is converted
to MathML at build time by docutils' own converter (:mod:`docutils.utils.math.latex2mathml`,
docutils ships with Sphinx), and the browser typesets the ``<math>`` elements natively.

No script, font or style sheet is fetched at build or view time (Sphinx's default MathJax
renderer loads MathJax from a CDN).  A formula the converter does not understand is a build
warning, so ``sphinx -W`` fails on it instead of printing raw LaTeX.
"""

from __future__ import annotations

import re
from pathlib import Path

from docutils import nodes
from docutils.utils.math import latex2mathml
from sphinx.locale import _
from sphinx.util import logging
from sphinx.util.math import get_node_equation_number

logger = logging.getLogger(__name__)

#: an accent on one symbol or group followed by a subscript (``\hat x_k``, ``\hat{\mathcal{S}}_j``)
_ACCENT_SUB = re.compile(r"(\\(?:hat|tilde|bar|widehat|widetilde|dot|vec)\s*"
                         r"(?:\{(?:[^{}]|\{[^{}]*\})*\}|\\[A-Za-z]+|[A-Za-z0-9]))\s*_")


def _accent_subscripts(tex: str) -> str:
    r"""``\hat{x}^{}_k`` for ``\hat x_k``: docutils' converter sets the subscript of an
    accented symbol *under* it (``munderover``); with an empty superscript the subscript is
    attached beside the accented symbol, as LaTeX sets it."""
    return _ACCENT_SUB.sub(r"{\1}^{}_", tex)


def _convert(self, node, tex: str, block: bool) -> str:
    """MathML of ``tex``; the LaTeX itself, escaped, with a warning if it does not convert."""
    try:
        return latex2mathml.tex2mathml(_accent_subscripts(tex), as_block=block)
    except Exception as exc:  # noqa: BLE001 - docutils raises SyntaxError, KeyError, ...
        logger.warning("cannot convert this LaTeX to MathML (%s): %s", exc, tex,
                       location=node, type="math", subtype="mathml")
        return f'<code class="math-error">{self.encode(tex)}</code>'


def visit_math(self, node: nodes.math) -> None:
    """Inline math (``:math:`...```): a ``<math>`` element in the line."""
    self.body.append(self.starttag(node, "span", "", CLASS="math notranslate"))
    self.body.append(_convert(self, node, node.astext(), block=False) + "</span>")
    raise nodes.SkipNode


def visit_displaymath(self, node: nodes.math_block) -> None:
    """Display math (``.. math::``): one ``<math display="block">`` per equation (parts
    separated by a blank line), multi-line parts aligned; the equation number as Sphinx's
    MathJax renderer writes it (``<span class="eqno">``)."""
    self.body.append(self.starttag(node, "div", CLASS="math notranslate"))
    if node["number"]:
        number = get_node_equation_number(self, node)
        self.body.append(f'<span class="eqno">({number})')
        self.add_permalink_ref(node, _("Link to this equation"))
        self.body.append("</span>")
    for part in (p for p in node.astext().split("\n\n") if p.strip()):
        if r"\\" in part and r"\begin" not in part:
            part = r"\begin{aligned}" + part + r"\end{aligned}"
        self.body.append(_convert(self, node, part, block=True))
    self.body.append("</div>\n")
    raise nodes.SkipNode


def _add_static(app) -> None:
    """Serve ``mathml_static/mathml.css`` (the math font) beside the site's own static files."""
    app.config.html_static_path.append(str(Path(__file__).resolve().parent / "mathml_static"))


def setup(app):
    app.add_html_math_renderer("mathml", (visit_math, None), (visit_displaymath, None))
    app.connect("builder-inited", _add_static)
    app.add_css_file("mathml.css")
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
