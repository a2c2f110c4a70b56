"""A documented output is one the current code produces: the Python examples whose output
docs/python.md shows are run here and compared with the text (the command line's blocks are checked by
crates/cli/tests/docs_cli.rs, with the same markers).

A block marked ``<!-- doc-check: python output of: FILE -->`` (FILE relative to the repository root) is the
standard output of ``python FILE`` run in a scratch folder; a block marked ``<!-- doc-check: python source
of: FILE -->`` is FILE itself, so that the code shown is the code whose output is shown (audit s25 L-1).
``DOC_CHECK_UPDATE=1`` rewrites the blocks."""

import os
import pathlib
import re
import subprocess
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
MARK = re.compile(r"^<!-- doc-check: python output of: (\S+) -->$")
SOURCE_MARK = re.compile(r"^<!-- doc-check: python source of: (\S+) -->$")


def blocks(doc, mark=MARK):
    """(script, index of the opening fence, index of the closing fence) of every marked block."""
    lines = doc.splitlines()
    for i, line in enumerate(lines):
        m = mark.match(line.strip())
        if m:
            start = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            end = next(j for j in range(start + 1, len(lines)) if lines[j].startswith("```"))
            yield m.group(1), start, end


@pytest.mark.parametrize("doc", ["docs/python.md"])
def test_documented_python_output_is_what_the_code_prints(doc, tmp_path):
    path = REPO / doc
    lines = path.read_text().splitlines()
    found = list(blocks(path.read_text()))
    assert found, f"{doc}: no marked block"
    mismatches = []
    for script, start, end in reversed(found):
        r = subprocess.run(
            [sys.executable, str(REPO / script)], cwd=tmp_path, capture_output=True, text=True
        )
        assert r.returncode == 0, f"{script} failed:\n{r.stderr}"
        have = [l.rstrip() for l in r.stdout.splitlines()]
        want = [l.rstrip() for l in lines[start + 1 : end]]
        if have != want:
            mismatches.append(f"{doc}:{start + 2}: output of {script}:\n--- documented\n"
                              + "\n".join(want) + "\n--- now\n" + "\n".join(have))
            lines[start + 1 : end] = have
    if mismatches and os.environ.get("DOC_CHECK_UPDATE"):
        path.write_text("\n".join(lines) + "\n")
    else:
        assert not mismatches, "\n\n".join(mismatches)


@pytest.mark.parametrize("doc", ["docs/python.md"])
def test_documented_python_source_is_the_script(doc):
    # The worked example's code block is the script whose output the next block shows, verbatim (audit
    # s25 L-1: the block was a shorter script that printed 3 of the 12 lines shown).
    path = REPO / doc
    text = path.read_text()
    lines = text.splitlines()
    found = list(blocks(text, SOURCE_MARK))
    assert found, f"{doc}: no block marked as a script's source"
    shown_output = {script for script, _, _ in blocks(text)}
    mismatches = []
    for script, start, end in reversed(found):
        assert script in shown_output, f"{doc}: the source of {script} is shown but not its output"
        have = (REPO / script).read_text().splitlines()
        if lines[start + 1 : end] != have:
            mismatches.append(f"{doc}:{start + 2}: the block is not {script}")
            lines[start + 1 : end] = have
    if mismatches and os.environ.get("DOC_CHECK_UPDATE"):
        path.write_text("\n".join(lines) + "\n")
    else:
        assert not mismatches, "\n".join(mismatches)
