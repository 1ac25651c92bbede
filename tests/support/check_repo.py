#!/usr/bin/env python3
"""The repository stands alone and speaks of its features: a lint over every tracked file.

Fails (exit 1, one line per finding) when a tracked file
  - refers to a path above the repository root (a relative path or Markdown link that leaves it),
    or to the team's reading material outside it;
  - mentions an issue or session number in the README, the docs, test names or comments (bench/results,
    the lab notebook of the benchmarks, is exempt);
  - cites `methods/<page> §N` where docs/methods/<page>.md has no section N;
  - links (Markdown) to a file of the repository that does not exist, or names a
    bench/results/... path outside bench/results that does not exist.

usage: check_repo.py ROOT          lint ROOT
       check_repo.py --self-test    a tree with one defect of each kind must give each finding
"""
import os
import re
import subprocess
import sys

ROOT = os.path.realpath(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] != "--self-test" else ".")
SELF = os.path.relpath(os.path.realpath(__file__), ROOT)

TEXT_EXT = {".cpp", ".hpp", ".h", ".py", ".sh", ".md", ".txt", ".cmake", ".json", ".in", ".yml", ".yaml", ""}

# Built from pieces so that this file does not match itself.
OUTSIDE = re.compile(r"\.\./" + "shared|" + "shared/" + "spec/|" + r"\b[Ss]pec 0[1-4]\b|\b(?:STYLE|DESIGN|ECOSYSTEM)" + r"\.md")
ISSUE = re.compile(r"\b[Ii]ssues?[ -]#?\d+\b|\b[Ii]ssue #\d+|\b[Ss]essions? \d+\b")
METHODS_REF = re.compile(r"methods/([a-z-]+) §(\d+(?:\.\d+)?)")
MD_LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)]*)?\)")
RELATIVE = re.compile(r"(?<![\w.])((?:\.\./)+[\w./-]*)")
RESULTS = re.compile(r"bench/results/[A-Za-z0-9_./-]*[A-Za-z0-9_/-]")


def tracked_files():
    try:
        out = subprocess.run(["git", "-C", ROOT, "ls-files", "-z"], check=True, capture_output=True).stdout
        files = [f for f in out.decode().split("\0") if f]
        return [f for f in files if os.path.exists(os.path.join(ROOT, f))]
    except (OSError, subprocess.CalledProcessError):
        files = []
        for d, dirs, names in os.walk(ROOT):
            dirs[:] = [x for x in dirs if x not in {".git", "build", "out"} and not x.startswith("out-")]
            files += [os.path.relpath(os.path.join(d, n), ROOT) for n in names]
        return files


def headings(page):
    """Section numbers of docs/methods/<page>.md: '## 4.' -> '4', '### 4.2 ...' -> '4.2'."""
    path = os.path.join(ROOT, "docs", "methods", page + ".md")
    if not os.path.exists(path):
        return None
    found = set()
    with open(path, encoding="utf-8") as f:
        for line in f:
            m = re.match(r"#{2,4}\s+(\d+(?:\.\d+)*)\.?\s", line)
            if m:
                found.add(m.group(1))
    return found


def inside(path):
    p = os.path.realpath(path)
    return p == ROOT or p.startswith(ROOT + os.sep)


def lint():
    findings = []
    sections = {}
    files = tracked_files()
    for rel in files:
        if rel == SELF or os.path.splitext(rel)[1] not in TEXT_EXT:
            continue
        try:
            with open(os.path.join(ROOT, rel), encoding="utf-8") as f:
                lines = f.read().splitlines()
        except (UnicodeDecodeError, IsADirectoryError):
            continue
        notebook = rel.startswith("bench/results/")
        here = os.path.dirname(os.path.join(ROOT, rel))
        for n, line in enumerate(lines, 1):
            where = f"{rel}:{n}"
            if OUTSIDE.search(line):
                findings.append(f"{where}: refers to material outside the repository: {line.strip()[:120]}")
            for m in RELATIVE.finditer(line):
                if not inside(os.path.join(here, m.group(1))):
                    findings.append(f"{where}: path above the repository root: {m.group(1)}")
            if notebook:
                continue
            if ISSUE.search(line):
                findings.append(f"{where}: mentions an issue or session number: {line.strip()[:120]}")
            for m in METHODS_REF.finditer(line):
                page, sec = m.group(1), m.group(2)
                if page not in sections:
                    sections[page] = headings(page)
                if sections[page] is None:
                    findings.append(f"{where}: cites methods/{page}, but docs/methods/{page}.md does not exist")
                elif sec not in sections[page]:
                    findings.append(f"{where}: cites methods/{page} §{sec}, which docs/methods/{page}.md does not have")
            for m in RESULTS.finditer(line):
                if not os.path.exists(os.path.join(ROOT, m.group(0))):
                    findings.append(f"{where}: names {m.group(0)}, which does not exist")
            if rel.endswith(".md"):
                for m in MD_LINK.finditer(line):
                    target = m.group(1)
                    if re.match(r"[a-z]+:", target):
                        continue
                    p = os.path.join(here, target)
                    if not inside(p):
                        findings.append(f"{where}: link leaves the repository: {target}")
                    elif not os.path.exists(p):
                        findings.append(f"{where}: link to a missing file: {target}")
    return files, findings


def self_test():
    """Every rule fires on a tree made to break it, and a clean tree passes."""
    import tempfile
    global ROOT, SELF
    defects = {
        "a.cpp": "// see " + "../" + "shared/notes.md\n",
        "b.md": "As in " + "spec" + " 02 §4, we step.\n",
        "c.hpp": "/// fixed for " + "iss" + "ue 7\n",
        "d.md": "See [x](../../../elsewhere.md).\n",
        "e.md": "Read [y](docs/missing.md).\n",
        "f.cpp": "// methods/shells §99 says so\n",
        "g.cpp": "// bench/results/nothing_here/ holds it\n",
    }
    expected = {"a.cpp": "outside", "b.md": "outside", "c.hpp": "issue or session number", "d.md": "leaves",
                "e.md": "missing file", "f.cpp": "does not have", "g.cpp": "does not exist"}
    with tempfile.TemporaryDirectory() as d:
        os.makedirs(os.path.join(d, "docs", "methods"))
        with open(os.path.join(d, "docs", "methods", "shells.md"), "w") as f:
            f.write("## 1. Intro\n### 1.2 More\n")
        with open(os.path.join(d, "clean.md"), "w") as f:
            f.write("See methods/shells §1.2 and [the page](docs/methods/shells.md).\n")
        ROOT, SELF = os.path.realpath(d), "none"
        _, clean = lint()
        if clean:
            print("self-test: a clean tree gave findings:", clean)
            return 1
        for name, text in defects.items():
            with open(os.path.join(d, name), "w") as f:
                f.write(text)
        _, findings = lint()
    bad = 0
    for name, what in expected.items():
        if not any(f.startswith(name + ":") and what in f for f in findings):
            print(f"self-test: no '{what}' finding for {name}: {findings}")
            bad += 1
    print(f"check_repo self-test: {len(expected) - bad} of {len(expected)} defects found")
    return 1 if bad else 0


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--self-test":
        return self_test()
    files, findings = lint()
    for f in findings:
        print(f)
    print(f"check_repo: {len(files)} tracked files, {len(findings)} findings")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
