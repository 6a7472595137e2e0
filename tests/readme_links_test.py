#!/usr/bin/python3
"""Every relative link in every README (and in the docs they link) resolves, and the top-level
README stays short enough to read in ten minutes (at most 200 lines).

A link [text](target) whose target is not a URL must name a file or directory that exists,
relative to the Markdown file, and its #anchor, if any, a heading of the target (GitHub's
slugs: lower case, punctuation dropped, spaces to '-').

Usage: readme_links_test.py WORKSPACE
       readme_links_test.py --self-test WORKSPACE   check that a broken link is caught
"""
import pathlib
import re
import shutil
import sys
import tempfile

LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"^```.*?^```", re.M | re.S)
HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$", re.M)


def slug(heading):
    text = re.sub(r"`([^`]*)`", r"\1", heading).strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    text = FENCE.sub("", path.read_text(encoding="utf-8"))
    return {slug(h) for h in HEADING.findall(text)}


def markdown_files(root):
    files = [root / "README.md"] + sorted(root.glob("src/*/README.md"))
    files += sorted(root.glob("docs/**/*.md"))
    return [f for f in files if f.is_file()]


MAX_TOP_README_LINES = 200


def check(root):
    problems = []
    files = markdown_files(root)
    top = root / "README.md"
    if top.is_file():
        lines = len(top.read_text(encoding="utf-8").splitlines())
        if lines > MAX_TOP_README_LINES:
            problems.append(f"README.md has {lines} lines; keep it to {MAX_TOP_README_LINES} "
                            "(move campaigns and history to dated files under docs/)")
    links = 0
    for md in files:
        text = FENCE.sub("", md.read_text(encoding="utf-8"))
        for target in LINK.findall(text):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
                continue
            links += 1
            path_part, _, anchor = target.partition("#")
            dest = (md.parent / path_part).resolve() if path_part else md
            rel = md.relative_to(root)
            if not dest.exists():
                problems.append(f"{rel}: link to {target}: {path_part} does not exist")
                continue
            if anchor and dest.is_file() and dest.suffix == ".md" and anchor not in anchors(dest):
                problems.append(f"{rel}: link to {target}: no heading '#{anchor}' in {dest.name}")
    return problems, files, links


def self_test(root):
    scratch = pathlib.Path(tempfile.mkdtemp())
    try:
        (scratch / "src" / "p").mkdir(parents=True)
        (scratch / "README.md").write_text("# Top\n\n## Real part\n\n[ok](#real-part) "
                                           "[p](src/p/README.md#usage)\n")
        (scratch / "src" / "p" / "README.md").write_text("# p\n\n## Usage\n\n[up](../../README.md)\n")
        if check(scratch)[0]:
            print("self-test: good links were refused:", check(scratch)[0])
            return 1
        (scratch / "src" / "p" / "README.md").write_text(
            "# p\n\n## Usage\n\n[gone](missing.md) [anchor](../../README.md#no-such-part)\n")
        found = check(scratch)[0]
        if len(found) != 2:
            print("self-test: expected 2 broken links, found", found)
            return 1
        print("self-test: caught", "; ".join(found))
        return 0
    finally:
        shutil.rmtree(scratch)


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--self-test":
        return self_test(pathlib.Path(sys.argv[2]))
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    problems, files, links = check(pathlib.Path(sys.argv[1]).resolve())
    for p in problems:
        print("LINK:", p)
    print(f"readme links: {links} relative links in {len(files)} files,",
          "FAIL" if problems else "OK")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
