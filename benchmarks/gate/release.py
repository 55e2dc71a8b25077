"""``make release``: measure again every dated report the code has changed, bump the version
and tag it.

The published tables are kept current at every landing (``make bench``); the dated reports of
the second tier (:mod:`.dated`) are measured again at a release.  :func:`plan` names the make
targets of the dated reports with a changed row (or no record); ``make release`` runs them,
then :func:`bump` writes the new version into ``pyproject.toml`` and ``CITATION.cff``, opens its
``CHANGELOG.md`` entry with what the release measured again, commits and tags ``vX.Y.Z``.
"""

from __future__ import annotations

import re
import subprocess
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ConfigError
from ..report.citation import project_version
from ..store.fingerprint import Fingerprinter
from ..store.graph import ROOT, ModuleGraph
from . import dated

#: the parts of a version a release may bump
PARTS = ("major", "minor", "patch")
#: the files that carry the version (and the pattern of its line)
VERSION_FILES = {"pyproject.toml": r'^(version\s*=\s*")([^"]+)(")',
                 "CITATION.cff": r"^(version:\s*)(\S+)()"}


def plan(root: Path = ROOT) -> list[str]:
    """The make targets that measure again the dated reports of ``root/reports`` with a row
    the code has changed since, or no record of their rows (in the order of :data:`.dated`)."""
    fingerprinter = Fingerprinter(ModuleGraph(root))
    out = []
    for name in dated.dated_reports(root / "reports"):
        changed = dated.changed_rows(name, fingerprinter, root)
        if changed is None or changed:
            target = dated.DATED[name].target if name in dated.DATED else dated.STORED[name]
            if target not in out:
                out.append(target)
    return out


def next_version(current: str, part: str) -> str:
    """``current`` (``MAJOR.MINOR.PATCH``) with ``part`` bumped and the parts after it reset."""
    if part not in PARTS:
        raise ConfigError(f"release: cannot bump '{part}' (one of {', '.join(PARTS)})")
    found = re.fullmatch(r"(\d+)\.(\d+)\.(\d+)", current)
    if not found:
        raise ConfigError(f"release: version '{current}' is not MAJOR.MINOR.PATCH")
    nums = [int(x) for x in found.groups()]
    i = PARTS.index(part)
    nums = nums[:i] + [nums[i] + 1] + [0] * (2 - i)
    return ".".join(map(str, nums))


def _set_version(root: Path, new: str) -> str:
    """Write ``new`` into every file of :data:`VERSION_FILES`; returns the old version."""
    old = ""
    for name, pattern in VERSION_FILES.items():
        path = root / name
        text = path.read_text(encoding="utf-8")
        found = re.search(pattern, text, re.M)
        if not found:
            raise ConfigError(f"release: no version line in {name}")
        old = old or found.group(2)
        path.write_text(re.sub(pattern, lambda m: m.group(1) + new + m.group(3), text, count=1,
                               flags=re.M), encoding="utf-8")
    return old


def changelog_entry(new: str, measured: list[str], date: str) -> str:
    """The opening lines of the release's ``CHANGELOG.md`` entry: what it measured again."""
    what = (", ".join(f"`reports/{n}.md`" for n in measured)
            or "none (no dated report had a changed row)")
    return (f"## [{new}] - {date}\n\nRelease: every published table current (`make bench`); "
            f"dated reports measured again by this release: {what}.\n\n")


#: the heading of the changes not yet released (their items become the release's)
UNRELEASED = "## [Unreleased]\n"


def with_entry(text: str, entry: str) -> str:
    """``CHANGELOG.md`` ``text`` with the release's ``entry`` above the newest version; an
    ``[Unreleased]`` section becomes the release's (its heading replaced by the entry)."""
    first = text.index("\n## [") + 1
    if text.startswith(UNRELEASED, first):
        return text[:first] + entry + text[first + len(UNRELEASED):].lstrip("\n")
    return text[:first] + entry + text[first:]


def bump(part: str = "patch", root: Path = ROOT) -> str:
    """Bump the version, open its CHANGELOG entry, commit and tag; returns the new version.

    Refused (one line) where a dated report still has a changed row (``make release`` measures
    them first) or ``root`` is not a git checkout."""
    left = plan(root)
    if left:
        raise ConfigError(f"release: dated reports still measured by older code "
                          f"(`make {' '.join(left)}` first)")
    records = dated.read_records(root)
    current = project_version()
    new = next_version(current, part)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root,
                          capture_output=True, text=True).stdout.strip()
    if not head:
        raise ConfigError(f"release: {root} is not a git checkout (nothing to tag)")
    measured = sorted(n for n, r in records.items() if r.get("version") == current
                      and r.get("commit", "").startswith(head))
    date = datetime.now(timezone.utc).date().isoformat()
    _set_version(root, new)
    log = root / "CHANGELOG.md"
    text = log.read_text(encoding="utf-8")
    log.write_text(with_entry(text, changelog_entry(new, measured, date)), encoding="utf-8")
    files = [*VERSION_FILES, "CHANGELOG.md", "results", "reports"]
    subprocess.run(["git", "add", "--", *files], cwd=root, check=True)
    subprocess.run(["git", "commit", "-q", "-m", f"Release {new}"], cwd=root, check=True)
    subprocess.run(["git", "tag", f"v{new}"], cwd=root, check=True)
    return new
