"""Every relative link of README.md and docs/*.md points to a file of the repository, and a
link to a heading of a Markdown file names a heading that exists there. (Inside docs/ the
Sphinx build of `make docs` checks links and anchors too, as warnings that fail it; README.md
is not part of that build, and external http(s) links cannot be fetched offline, so they
are only checked to be well formed.)"""
import pathlib
import re

import pytest

from helpers import ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

_FENCE = re.compile(r"^(```|~~~).*?^\1", re.S | re.M)
_CODE = re.compile(r"`[^`\n]*`")
_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")
_HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$", re.M)


def links(text: str) -> list[str]:
    """The targets of Markdown links and images, code blocks and code spans left out."""
    text = _CODE.sub("", _FENCE.sub("", text))
    return _LINK.findall(text)


def slug(heading: str) -> str:
    """The anchor of a heading, as GitHub and MyST (myst_heading_anchors) make it for plain
    headings: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: pathlib.Path) -> set[str]:
    return {slug(h) for h in _HEADING.findall(_FENCE.sub("", page.read_text()))}


def target_file(page: pathlib.Path, path: str) -> pathlib.Path:
    """The file a relative link names. The demo pages docs/demos/<name>.md are made from
    demos/<name>.py when the documentation is built."""
    target = (page.parent / path).resolve()
    demos = (ROOT / "docs" / "demos").resolve()
    if target.parent == demos and target.suffix == ".md":
        return ROOT / "demos" / f"{target.stem}.py"
    return target


def broken(page: pathlib.Path) -> list[str]:
    wrong = []
    for link in links(page.read_text()):
        if re.match(r"[a-z]+:", link):
            if not re.fullmatch(r"(https?://[\w.-]+\.[a-z]{2,}(/\S*)?|mailto:\S+@\S+)", link):
                wrong.append(f"{link}: not a well-formed external link")
            continue
        path, _, anchor = link.partition("#")
        target = target_file(page, path) if path else page
        if not target.exists():
            wrong.append(f"{link}: no file {target}")
        elif anchor and target.suffix == ".md" and anchor not in anchors(target):
            wrong.append(f"{link}: no heading '#{anchor}' in {target.name}")
    return wrong


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_to_files(page):
    wrong = broken(page)
    assert not wrong, f"{page.relative_to(ROOT)}:\n" + "\n".join(wrong)


def test_the_readme_links_the_documentation():
    """README.md links every documentation page it summarises, and the licence and the
    citation file."""
    targets = {link.partition("#")[0] for link in links((ROOT / "README.md").read_text())}
    for wanted in ("docs/installation.md", "docs/running.md", "docs/scenes.md", "docs/api.md",
                   "docs/model.md", "docs/architecture.md", "docs/verification.md",
                   "docs/scaling.md", "docs/reliability.md", "docs/limitations.md",
                   "LICENSE", "CITATION.cff"):
        assert wanted in targets, f"README.md does not link {wanted}"


def test_the_check_sees_a_broken_link(tmp_path):
    """Control: a missing file, a missing heading and a link inside code."""
    (tmp_path / "other.md").write_text("# Other\n\n## A section, with punctuation!\n")
    page = tmp_path / "page.md"
    page.write_text("[ok](other.md#a-section-with-punctuation) [gone](missing.md) "
                    "[bad anchor](other.md#nowhere) ![img](fig.png)\n"
                    "`[in code](nowhere.md)`\n```\n[in a block](nowhere.md)\n```\n")
    wrong = broken(page)
    assert len(wrong) == 3, wrong
    assert any("missing.md" in w for w in wrong) and any("#nowhere" in w for w in wrong)
    assert any("fig.png" in w for w in wrong)
