"""A documented output is one the current code produces: the Python examples whose output
docs/python.md shows are run here and compared with the text (the command line's blocks are checked by
crates/cli/tests/docs_cli.rs, with the same markers).

A block marked ``<!-- doc-check: python output of: FILE -->`` (FILE relative to the repository root) is the
standard output of ``python FILE`` run in a scratch folder. ``DOC_CHECK_UPDATE=1`` rewrites the blocks."""

import os
import pathlib
import re
import subprocess
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
MARK = re.compile(r"^<!-- doc-check: python output of: (\S+) -->$")


def blocks(doc):
    """(script, index of the opening fence, index of the closing fence) of every marked block."""
    lines = doc.splitlines()
    for i, line in enumerate(lines):
        m = MARK.match(line.strip())
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
