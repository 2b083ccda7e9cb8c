"""The message tables of the documentation (a problem per row, the messages the code gives for it quoted in code
spans of the last column), read from a page and compared with the messages the code gives, message by message.

A message that holds a backtick is quoted in a longer backtick string (CommonMark code spans:
``` `` expected a `mast run` output folder `` ```); ``...`` in a quoted message stands for any text, ``DIR`` for a
folder, and a message may start with the file's folder.
"""

from __future__ import annotations

import re
from pathlib import Path

#: a code span: a string of backticks, the shortest text, the same string of backticks (CommonMark 6.1)
SPAN = re.compile(r"(?<!`)(?P<ticks>`+)(?!`)(?P<code>.+?)(?<!`)(?P=ticks)(?!`)", re.S)


def code_spans(text: str) -> list[str]:
    """The contents of the code spans of ``text``, in order (one space stripped from each end when both have one and
    the content is not all spaces, as CommonMark renders them)."""
    spans = []
    for match in SPAN.finditer(text):
        code = match["code"]
        if len(code) > 2 and code[0] == code[-1] == " " and code.strip():
            code = code[1:-1]
        spans.append(code)
    return spans


def documented_messages(page: Path, heading: str) -> dict[str, list[str]]:
    """The table under ``heading`` in ``page``: problem (its first column) -> every code span of its last column."""
    text = page.read_text()
    if heading not in text:
        raise ValueError(f"{page}: no heading {heading!r}")
    table = text[text.index(heading) :]
    table = table[table.index("\n|") + 1 : table.index("\n\n", table.index("\n|"))]
    rows = {}
    for line in table.splitlines()[2:]:
        problem, message = line.strip().strip("|").split(" | ", 1)
        rows[problem.strip()] = code_spans(message)
    return rows


def documented_mismatches(documented: dict[str, list[str]], actual: dict[str, list[str]]) -> list[str]:
    """The rows whose documented messages are not the actual ones, message by message: a row quotes as many as the
    code gives, each the whole message (module docstring)."""
    problems = []
    for problem, messages in actual.items():
        quoted = documented[problem]
        if len(quoted) != len(messages):
            problems.append(
                f"{problem}: the page quotes {len(quoted)} message(s) {quoted!r}, the code gives {messages!r}"
            )
            continue
        for k, (said, message) in enumerate(zip(quoted, messages), 1):
            pattern = re.escape(said).replace(re.escape("..."), ".*").replace("DIR", ".+")
            if not re.fullmatch(f"(?:.*/)?{pattern}", message, re.S):
                problems.append(f"{problem}: message {k}: the page says {said!r}, the code {message!r}")
    return problems
