#!/usr/bin/env python3
"""Runs the console blocks of a Markdown page and compares what they print with what the page shows.

    doc_runner.py DOC.md --repo DIR --bin DIR [--shared DIR] [--work DIR] [--list | --show]

Every ```console block is a test: its `$ ` lines are commands (a line ending in `\\` continues on the next, so does
a line starting `> `, and a `<<WORD` here-document takes the lines up to WORD); the lines after a command, up to
the next `$ `, are the output it must print (stdout and stderr together). The page's commands run one after
another in bash, in one work folder per page that looks like the repository root: every top-level entry of the
repository is linked into it, `build` points at the build folder, `logs/` is a folder of its own (the
repository's logs linked in) so what the commands write stays out of the checkout, and `../shared` beside it is
the shared data's parent (docs say `../shared/data`). The build's `bin/` comes first on PATH, so `driftlab` and
`build/bin/driftlab` both work, and the conversion cache starts empty (XDG_CACHE_HOME in the work folder).

The expected text:
  - a line `...` (indented or not) stands for any number of lines, none included;
  - `...` inside a line stands for any text on that line (times, paths, the rest of a long line);
  - numbers are compared as numbers: an integer exactly, a decimal within one unit of its last printed digit
    (0.048 takes 0.047 to 0.049), or within the tolerance the block states; `1,234` is a number;
  - runs of spaces match runs of spaces of any length (a wider number shifts a table's columns).

An HTML comment on the line just before the block sets how it runs (several may follow each other):
  <!-- doc-test: tolerance 0.5% -->    numbers within 0.5% (relative) or `tolerance 0.01` (absolute)
  <!-- doc-test: skip REASON -->       not run (a live network, output only, too long for CI); listed with REASON
  <!-- doc-test: timeout 300 -->       seconds per command (default 120)
A console block without a command must be marked skip. A command's exit status must be 0 unless its block says
`<!-- doc-test: exit N -->`.

Exit status: 0 when every block matched, 1 otherwise, 77 (skipped) when the page reads ../shared/data and there is
none; each failure shows the page, the line, the command and a diff of the expected against what it printed.
--show prints every command's whole output, to paste under it after a change (then elide with `...`): regenerate
a figure, never type it.
"""

import argparse
import difflib
import os
import re
import shutil
import subprocess
import sys
import time

ANNOTATION = re.compile(r"^\s*<!--\s*doc-test:\s*(\w+)\s*(.*?)\s*-->\s*$")
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*(\S*)")
NUMBER = r"[-+]?\d+(?:,\d{3})*(?:\.\d+)?(?:[eE][-+]?\d+)?"
# A number in the expected text: not glued to a word before it (p99, IMU2), nor part of a longer number.
NUMBER_TOKEN = re.compile(r"(?<![A-Za-z0-9_.,])" + NUMBER + r"(?![0-9])")
HEREDOC = re.compile(r"<<-?\s*['\"]?(\w+)['\"]?")


class Block:
    def __init__(self, doc, line):
        self.doc, self.line = doc, line
        self.options = {}
        self.steps = []  # (line, command, expected lines)


def parse(path):
    """The console blocks of a page, each with its annotations and its (line, command, expected) steps."""
    lines = open(path, encoding="utf-8").read().split("\n")
    blocks, pending, i = [], {}, 0
    while i < len(lines):
        m = ANNOTATION.match(lines[i])
        if m:
            key, value = m.group(1), m.group(2)
            if key not in ("skip", "tolerance", "timeout", "exit"):
                raise SystemExit(f"{path}:{i + 1}: unknown doc-test annotation '{key}'")
            if key == "skip" and not value:
                raise SystemExit(f"{path}:{i + 1}: doc-test: skip needs a reason")
            pending[key] = value
            i += 1
            continue
        f = FENCE.match(lines[i])
        if not f:
            if lines[i].strip():
                pending = {}
            i += 1
            continue
        indent, fence, lang = f.group(1), f.group(2), f.group(3)
        body, j = [], i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence[:3]):
            body.append(lines[j][len(indent):] if lines[j].startswith(indent) else lines[j].lstrip())
            j += 1
        if lang == "console":
            block = Block(path, i + 1)
            block.options = pending
            steps, k = [], 0
            while k < len(body):
                if not body[k].startswith("$ "):
                    if not steps:
                        if block.options.get("skip") is None:
                            raise SystemExit(f"{path}:{i + 2 + k}: console block output before any `$ ` command; "
                                             "give it a command or mark it <!-- doc-test: skip REASON -->")
                        k += 1
                        continue
                    steps[-1][2].append(body[k])
                    k += 1
                    continue
                start, command = i + 2 + k, body[k][2:]
                k += 1
                while k < len(body) and (command.endswith("\\") or body[k].startswith("> ")):
                    command += "\n" + (body[k][2:] if body[k].startswith("> ") else body[k])
                    k += 1
                for word in HEREDOC.findall(command):
                    while k < len(body):
                        command += "\n" + body[k]
                        k += 1
                        if body[k - 1].strip() == word:
                            break
                steps.append((start, command, []))
            block.steps = steps
            blocks.append(block)
        elif lang in ("sh", "bash", "shell") and any(l.startswith("$ ") for l in body):
            raise SystemExit(f"{path}:{i + 1}: a ```{lang} block with `$ ` prompts: make it ```console")
        pending = {}
        i = j + 1
    return blocks


def line_pattern(expected):
    """A regex for one expected line, and the numbers it expects (in order)."""
    pattern, numbers, pos = "", [], 0
    for part in re.split(r"(\.\.\.)", expected.rstrip()):
        if part == "...":
            pattern += ".*?"
            continue
        for m in NUMBER_TOKEN.finditer(part):
            pattern += literal(part[pos:m.start()])
            pattern += "(" + NUMBER + ")"
            numbers.append(m.group(0))
            pos = m.end()
        pattern += literal(part[pos:])
        pos = 0
    return re.compile(pattern + r"\s*"), numbers


def literal(text):
    return r"\s+".join(re.escape(t) for t in re.split(r"\s+", text)) if text else ""


def close(expected, got, tolerance):
    """Whether a number printed as `got` matches the page's `expected`: within the block's tolerance, or else (and
    always at least) an integer exactly and a decimal within one unit of its last printed digit."""
    e, g = float(expected.replace(",", "")), float(got.replace(",", ""))
    if tolerance is not None:
        value, relative = tolerance
        if abs(g - e) <= (value * abs(e) if relative else value) + 1e-12:
            return True
    mantissa = expected.replace(",", "").lstrip("+-").split("e")[0].split("E")[0]
    if "." not in mantissa:
        return e == g and ("e" in expected.lower() or "." not in got.split("e")[0].split("E")[0])
    unit = 10.0 ** -len(mantissa.split(".")[1])
    return abs(g - e) <= unit * 1.0001


def matches_line(expected, got, tolerance):
    pattern, numbers = line_pattern(expected)
    m = pattern.fullmatch(got)
    return bool(m) and all(close(e, g, tolerance) for e, g in zip(numbers, m.groups()))


def matches(expected, got, tolerance):
    """Whether the got lines match the expected ones, `...` lines taking any run of lines."""
    memo = {}

    def at(i, j):
        if (i, j) in memo:
            return memo[(i, j)]
        if i == len(expected):
            result = j == len(got)
        elif expected[i].strip() == "...":
            result = any(at(i + 1, k) for k in range(j, len(got) + 1))
        else:
            result = j < len(got) and matches_line(expected[i], got[j], tolerance) and at(i + 1, j + 1)
        memo[(i, j)] = result
        return result

    sys.setrecursionlimit(max(10000, 4 * (len(expected) + len(got))))
    return at(0, 0)


def tolerance_of(block):
    text = block.options.get("tolerance")
    if text is None:
        return None
    m = re.fullmatch(r"([0-9.]+)\s*(%?)", text)
    if not m:
        raise SystemExit(f"{block.doc}:{block.line}: doc-test tolerance '{text}': write 0.5% or 0.01")
    value = float(m.group(1))
    return (value / 100, True) if m.group(2) else (value, False)


def make_workdir(work, repo, build, shared):
    """A fresh folder that looks like the repository root, with `../shared` beside it when there is shared data."""
    if os.path.lexists(work):
        shutil.rmtree(work)
    os.makedirs(work)
    for name in os.listdir(repo):
        if name in ("build", "logs", ".git"):
            continue
        os.symlink(os.path.join(repo, name), os.path.join(work, name))
    os.symlink(build, os.path.join(work, "build"))
    os.makedirs(os.path.join(work, "logs"))
    logs = os.path.join(repo, "logs")
    for name in os.listdir(logs) if os.path.isdir(logs) else []:
        os.symlink(os.path.join(logs, name), os.path.join(work, "logs", name))
    beside = os.path.join(os.path.dirname(os.path.abspath(work)), "shared")
    if shared and os.path.isdir(shared):
        if os.path.lexists(beside):
            os.remove(beside)
        os.symlink(os.path.dirname(os.path.abspath(shared)), beside)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("doc")
    ap.add_argument("--repo", required=True, help="the repository root")
    ap.add_argument("--bin", required=True, help="the build's bin/ folder (driftlab and its helpers)")
    ap.add_argument("--shared", help="the shared data folder (../shared/data beside the repository)")
    ap.add_argument("--work", help="the work folder (default: BIN/../doc-tests/DOC), made afresh")
    ap.add_argument("--list", action="store_true", help="list the blocks and their commands; run nothing")
    ap.add_argument("--show", action="store_true", help="print what every command printed, whole (to paste into "
                    "the page after a change: then elide with `...`)")
    a = ap.parse_args()
    repo, bindir = os.path.abspath(a.repo), os.path.abspath(a.bin)
    build = os.path.dirname(bindir)
    doc = os.path.relpath(os.path.abspath(a.doc), repo)
    blocks = parse(os.path.join(repo, doc))
    if a.list:
        for b in blocks:
            state = f"skip: {b.options['skip']}" if "skip" in b.options else f"{len(b.steps)} commands"
            print(f"{doc}:{b.line}: {state}")
            for line, command, _ in b.steps:
                print(f"  {line}: $ {command}")
        return 0
    shared = a.shared
    runs = [c for b in blocks if "skip" not in b.options for _, c, _ in b.steps]
    if any("../shared/" in c for c in runs) and not (shared and os.path.isdir(shared)):
        print(f"{doc}: skipped: its commands read ../shared/data, and there is none ({shared})")
        return 77
    stem = os.path.splitext(os.path.basename(doc))[0]
    work = os.path.abspath(a.work or os.path.join(build, "doc-tests", stem))
    make_workdir(work, repo, build, shared)
    # A new user's machine: no conversion cache from an earlier run (an imported bag is converted afresh).
    env = dict(os.environ, PATH=bindir + os.pathsep + os.environ.get("PATH", ""), LC_ALL="C.UTF-8", TZ="UTC",
               XDG_CACHE_HOME=os.path.join(work, ".cache"))
    failures, skipped, ran, started = 0, 0, 0, time.monotonic()
    for b in blocks:
        if "skip" in b.options:
            print(f"{doc}:{b.line}: skipped: {b.options['skip']}")
            skipped += 1
            continue
        if not b.steps:
            print(f"{doc}:{b.line}: FAILED: a console block without a `$ ` command and not marked skip")
            failures += 1
            continue
        tolerance = tolerance_of(b)
        timeout = float(b.options.get("timeout", 120))
        want_status = int(b.options.get("exit", 0))
        for line, command, expected in b.steps:
            t0 = time.monotonic()
            try:
                p = subprocess.run(["bash", "-o", "pipefail", "-c", command], cwd=work, env=env,
                                   stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   timeout=timeout)
                out, status = p.stdout.decode("utf-8", "replace"), p.returncode
            except subprocess.TimeoutExpired as e:
                out, status = (e.stdout or b"").decode("utf-8", "replace") + f"\n[timed out after {timeout:g} s]", -1
            ran += 1
            got = out.split("\n")
            if got and got[-1] == "":
                got.pop()
            got = [g.rstrip() for g in got]
            while expected and not expected[-1].strip():
                expected = expected[:-1]
            ok = status == want_status and matches(expected, got, tolerance)
            took = time.monotonic() - t0
            if a.show:
                print(f"{doc}:{line}: $ {command}\n" + "\n".join(got) + f"\n[exit status {status}]")
            if ok:
                print(f"{doc}:{line}: ok ({took:.1f} s): $ {command.splitlines()[0]}")
                continue
            failures += 1
            print(f"\n{doc}:{line}: FAILED ({took:.1f} s)" +
                  (f": exit status {status}, expected {want_status}" if status != want_status else ""))
            print("  $ " + command.replace("\n", "\n    "))
            if tolerance is not None:
                print(f"  numbers within {b.options['tolerance']}")
            diff = difflib.unified_diff(expected, got, "expected (the page)", "got (the command)", lineterm="",
                                        n=3)
            print("\n".join("  " + d for d in diff) or "  (the output matches; the exit status does not)")
            print()
    took = time.monotonic() - started
    print(f"{doc}: {ran} commands run, {skipped} blocks skipped, {failures} failed, {took:.1f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
