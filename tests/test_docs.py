"""The documentation as tests: what README.md and docs/ tell a user to run runs, and what they state holds.

- Every fenced ``sh``/``bash``/``console``/``python`` block is marked by an HTML comment on the line before
  its fence (invisible in the rendered page):

  ``<!-- run -->``: the test suite runs the block as written (in a scratch folder where ``build/`` is a
  build of the tests' own, ``examples/``, ``docs/``, ``ssp/`` are the checkout's, ``.venv`` the tests'
  environment, ``../shared`` the measured data when present; a block that needs it is skipped without);
  ``<!-- run: OLD => NEW; OLD2 => NEW2 -->``: runs it with these text replacements (a short variant of
  a long run: fewer tests, a shorter stop time), each of which must apply;
  ``<!-- not run: REASON -->``: not run (a cluster, a run of many minutes, ``make test`` itself); its
  ``mast`` lines are still parsed.
- Every ``mast ...`` command in those blocks and in inline code (`` `mast run --native` ``) parses with
  ``mast``'s own parser: an option that was renamed or removed fails here with the page and line.
- The README's command table has a row per subcommand, naming every option of it.
- ``mast SUBCOMMAND --help`` describes every argument and shows every default.
- The figures the pages mark (``<!-- figure KEY -->...<!-- /figure -->``) agree with the code:
  docs/figures.py (cheap sources here; ``mast reproduce``'s in tests/test_reproduce.py).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import pytest

from mast import cli

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
RUNNABLE = ("sh", "bash", "console", "python")
MARK = re.compile(r"^<!-- (?P<kind>run|not run)(?::\s*(?P<arg>.*?))?\s*-->\s*$")
FENCE = re.compile(r"^(?P<indent>\s*)```(?P<lang>[\w-]*)\s*$")
HOW = (
    "mark it on the line before its fence: <!-- run -->, <!-- run: OLD => NEW --> (a short variant) or "
    "<!-- not run: REASON --> (tests/test_docs.py)"
)


def _figures():
    spec = importlib.util.spec_from_file_location("docs_figures", ROOT / "docs" / "figures.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


figures = _figures()


@dataclass
class Block:
    page: Path
    line: int  # of the opening fence
    lang: str
    text: str
    mark: str | None  # "run", "not run" or None
    arg: str  # the replacements of a run, the reason of a not run

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    lines = page.read_text().splitlines()
    out, k = [], 0
    while k < len(lines):
        fence = FENCE.match(lines[k])
        if not fence:
            k += 1
            continue
        end = next((j for j in range(k + 1, len(lines)) if lines[j].strip() == "```"), len(lines))
        mark = MARK.match(lines[k - 1].strip()) if k else None
        indent = len(fence["indent"])
        out.append(
            Block(
                page,
                k + 1,
                fence["lang"],
                "\n".join(l[indent:] for l in lines[k + 1 : end]),
                mark["kind"] if mark else None,
                (mark["arg"] or "") if mark else "",
            )
        )
        k = end + 1
    return out


ALL_BLOCKS = [b for page in PAGES for b in blocks(page)]
SHELL = [b for b in ALL_BLOCKS if b.lang in RUNNABLE]


def commands(text: str) -> list[str]:
    """The shell commands of a block: continuation lines joined, comments and prompts dropped."""
    joined = re.sub(r"\\\n\s*", " ", text)
    out = []
    for line in joined.splitlines():
        line = re.sub(r"^\$ ", "", line.strip())
        if line and not line.startswith("#"):
            out.append(line)
    return out


def test_every_shell_and_python_block_is_marked():
    unmarked = [f"{b.where} (```{b.lang})" for b in SHELL if b.mark is None]
    assert not unmarked, f"code blocks a user is told to run, neither run nor excused: {unmarked}: {HOW}"


def test_every_not_run_block_says_why():
    silent = [b.where for b in SHELL if b.mark == "not run" and not b.arg.strip()]
    assert not silent, f"<!-- not run: REASON -->: give the reason at {silent}"


# -- mast commands parse ---------------------------------------------------------------------------------
def _lenient_parser() -> argparse.ArgumentParser:
    """``mast``'s parser with types, choices and requirements off: a documented command with placeholders
    (``--out DIR``, ``[--quick]``) checks the option names and their arity only."""
    parser = _full_parser()
    for sub in _subparsers(parser).values():
        for action in sub._actions:
            action.type, action.required = None, False
            if not isinstance(action, cli.Renamed):
                action.choices = None
            if not action.option_strings and action.nargs in (None, "+"):
                action.nargs = "*"
            elif action.option_strings and action.nargs in (None, "+"):
                action.nargs = "?" if action.nargs is None else "*"  # inline: `mast run --set` names the option
        for group in sub._mutually_exclusive_groups:
            group.required = False
    return parser


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _full_parser() -> argparse.ArgumentParser:
    captured = {}
    original = argparse.ArgumentParser.parse_args

    def keep(self, *a, **k):
        captured["parser"] = self
        raise SystemExit(0)

    argparse.ArgumentParser.parse_args = keep
    try:
        with pytest.raises(SystemExit):
            cli.main(["build"])
    finally:
        argparse.ArgumentParser.parse_args = original
    return captured["parser"]


def _normalise(command: str) -> list[str]:
    """A documented command as tokens: optional brackets dropped, ``a|b`` alternatives -> a, ``...`` dropped."""
    command = command.split(" # ")[0].split("  #")[0]
    command = command.replace("\\|", "|").replace("[", " ").replace("]", " ")
    tokens = []
    for token in shlex.split(command, posix=True):
        if token in ("...", "|") or token.startswith("<"):
            continue
        tokens.append(token.split("|")[0])
    return tokens


INLINE = re.compile(r"`(mast [a-z][^`]*)`")


def documented_commands() -> list[tuple[str, str]]:
    """(where, command) of every ``mast`` command in a shell block or in inline code of the pages."""
    found = []
    for b in SHELL:
        if b.lang == "python":
            continue
        for c in commands(b.text):
            for part in re.split(r"\s*(?:&&|;|\|\|?)\s*", c):
                if part.startswith("mast "):
                    found.append((b.where, part))
    for page in PAGES:
        in_fence = False
        for number, line in enumerate(page.read_text().splitlines(), 1):
            if line.lstrip().startswith("```"):
                in_fence = not in_fence
                continue
            if not in_fence:
                found += [(f"{page.relative_to(ROOT)}:{number}", m) for m in INLINE.findall(line)]
    return found


def test_every_documented_mast_command_parses():
    parser = _lenient_parser()
    subcommands = _subparsers(parser)
    problems = []
    for where, command in documented_commands():
        tokens = _normalise(command)[1:]
        if not tokens or tokens[0] not in subcommands:
            problems.append(f"{where}: `{command}`: no subcommand {tokens[:1]} (mast has {', '.join(subcommands)})")
            continue
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                parser.parse_args(tokens)
            except SystemExit as stop:
                if stop.code:
                    problems.append(f"{where}: `{command}`: {err.getvalue().strip().splitlines()[-1]}")
    assert not problems, "documented commands that mast refuses (update the page):\n" + "\n".join(problems)


# -- README command table and --help -----------------------------------------------------------------------
def _readme_rows() -> dict[str, str]:
    """README command table: subcommand -> the text of its rows (a subcommand may have several)."""
    rows: dict[str, str] = {}
    for line in (ROOT / "README.md").read_text().splitlines():
        m = re.match(r"\|\s*`mast ([a-z][\w-]*)([^|]*(?:\\\|[^|]*)*)`\s*\|(.*)\|\s*$", line)
        if m:
            rows[m[1]] = rows.get(m[1], "") + " " + m[2] + " " + m[3]
    return rows


def _options(sub: argparse.ArgumentParser) -> list[str]:
    """The options a user may give (the long spelling of each), without --help and refused old spellings."""
    return [
        max(a.option_strings, key=len)
        for a in sub._actions
        if a.option_strings and a.help is not argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)
    ]


def test_readme_command_table_names_every_subcommand_and_option():
    rows = _readme_rows()
    problems = []
    for name, sub in _subparsers(_full_parser()).items():
        if name not in rows:
            problems.append(
                f"`mast {name}` has no row: add `| \\`mast {name} ...\\` | what it does |` "
                f"(its options: {' '.join(_options(sub))})"
            )
            continue
        missing = [o for o in _options(sub) if not re.search(re.escape(o) + r"(?![\w-])", rows[name])]
        if missing:
            problems.append(f"the row(s) of `mast {name}` do not name {', '.join(missing)} (see `mast {name} --help`)")
    stale = sorted(set(rows) - set(_subparsers(_full_parser())))
    if stale:
        problems.append(f"rows for subcommands mast does not have: {stale}")
    assert not problems, "README.md's command table against mast's parser:\n" + "\n".join(problems)


def test_help_describes_every_argument_and_shows_every_default():
    problems = []
    for name, sub in _subparsers(_full_parser()).items():
        text = sub.format_help()
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction) or action.help is argparse.SUPPRESS:
                continue
            label = action.dest if not action.option_strings else "/".join(action.option_strings)
            if not action.help:
                problems.append(f"mast {name} {label}: no help text")
                continue
            shown = (
                sub._get_formatter()._get_help_string(action) % {**vars(action), "prog": sub.prog}
                if "%(" in sub._get_formatter()._get_help_string(action)
                else action.help
            )
            if action.default not in (None, False, argparse.SUPPRESS) and "default" not in shown:
                problems.append(f"mast {name} {label}: default {action.default!r} not shown")
        assert "usage: mast " + name in text
    assert not problems, "\n".join(problems)


def test_one_meaning_per_option_name_model_is_a_parameter_set():
    """`--model` is diagnose's nominal parameter set; replay's former `--model SSP` is refused, naming the new
    spelling (the SSP as replay's first argument)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), pytest.raises(SystemExit) as stop:
        cli.main(["replay", "--model", "build/ssp/EMPS_bench.ssp", "--measured", "m", "--out", "o"])
    assert stop.value.code == 2
    assert "--model was renamed" in err.getvalue() and "mast replay SSP" in err.getvalue()
    subs = _subparsers(_full_parser())
    assert "--model" in _options(subs["diagnose"]) and "--model" not in _options(subs["replay"])


# -- figures ------------------------------------------------------------------------------------------------
def test_every_marked_figure_is_known():
    problems = [p for p in figures.check({}) if "is not in docs/figures.py" in p]
    assert not problems, "\n".join(problems)


def test_marked_figures_of_the_system_files_and_designs_agree():
    """The gains MAST.ssd binds (docs/controller.md), the designs' margins at home (docs/mechanism.md), the drive
    ratings (docs/sizing.md), the FMUs mast build writes and the archive limits (README, docs/interfaces.md)."""
    problems = figures.check(
        {
            "ssd": figures.source_ssd(),
            "designs": figures.source_designs(),
            "ratings": figures.source_ratings(),
            "build": figures.source_build(),
        }
    )
    assert not problems, "\n".join(problems)


def test_marked_workspace_figures_agree():
    """The designs' workspaces: docs/workspace.md (default grid), README "First results" (compare's quick grid)."""
    problems = figures.check(
        {"workspace": figures.source_workspace(), "workspace_quick": figures.source_workspace(quick=True)}
    )
    assert not problems, "\n".join(problems)


@pytest.mark.skipif(not figures.EMPS_RECORD.exists(), reason=f"{figures.EMPS_RECORD} not present")
def test_marked_emps_replay_figures_agree():
    """docs/emps.md: `mast replay` of the EMPS record with the published estimates and with the nominal model."""
    problems = figures.check({"emps": figures.source_emps()})
    assert not problems, "\n".join(problems)


def test_marked_hexapod_figures_agree():
    """docs/designs/6ups.md: the 6-UPS's margins and static forces at home, its workspaces on a coarse grid."""
    problems = figures.check({"hexapod": figures.source_hexapod()})
    assert not problems, "\n".join(problems)


def test_every_figure_source_is_checked_by_a_test():
    """A source added to docs/figures.py is compared with the pages somewhere (here or tests/test_reproduce.py)."""
    checked = {"ssd", "designs", "workspace", "workspace_quick", "reproduce", "ratings", "build", "emps", "hexapod"}
    assert set(figures.SOURCES) == checked, f"sources no test compares: {set(figures.SOURCES) - checked}"


def test_the_headline_figures_are_marked():
    """The figures a change most likely moves are generated into the pages, not typed."""
    text = (ROOT / "docs" / "reproduction.md").read_text()
    for key in ("reproduce.predictions_within", "reproduce.predictions", "reproduce.phase_10Hz_z"):
        assert f"<!-- figure {key} -->" in text, key


# -- timings ------------------------------------------------------------------------------------------------
# A timing (wall time of a command, a real-time factor, "x times faster", cases per second) depends on the machine
# and its load: a page states one only beside the benchmark that measures it (benchmarks/*.py, `mast bench`,
# `make bench...`), in the same paragraph or table row. Figures of simulated time (a 10 s run, a 1 ms cycle) are
# not timings and do not match.
_SECONDS = r"\d+(?:\.\d+)?\s*(?:s|ms|min|minutes?|seconds?|h|hours?)\b"
TIMING = re.compile(
    r"\b(?:takes?|took|taking|runs? in|ran in|wall(?:[- ]clock| time)?|elapsed)\b[^.;|]{0,30}?"
    + _SECONDS
    + r"|"
    + _SECONDS
    + r"[^.;|]{0,25}?\b(?:on (?:\d+|two|one|a|this|the) (?:cores?|CPUs?|machine|laptop)|wall|"
    r"per (?:case|run|simulation|co-simulation))\b"
    r"|real[- ]time factor[^.;|]{0,20}?\d|\d+(?:\.\d+)?\s*(?:x|times) (?:faster|slower|quicker)"
    r"|\d+(?:\.\d+)?\s*(?:cases|simulations|runs|steps)/s\b",
    re.I,
)
BENCHMARK = re.compile(r"benchmarks/\w+\.py|mast bench|make bench")
#: the bare timings the pages still state (issue 30): a page may hold at most this many; a timing moved beside its
#: benchmark lowers the count here (the test says so), a new bare one fails
KNOWN_BARE_TIMINGS = {
    "README.md": 2,
    "docs/batch.md": 3,
    "docs/controller.md": 1,
    "docs/designs/README.md": 1,
    "docs/diagnose.md": 6,
    "docs/emps.md": 1,
    "docs/interfaces.md": 1,
    "docs/native.md": 3,
    "docs/reproduction.md": 1,
    "docs/using-the-fmus.md": 1,
}


def _prose(text: str) -> Iterator[tuple[int, str]]:
    """(first line, text) of every paragraph and table row outside fenced blocks."""
    block: list[str] = []
    start, fenced = 1, False
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and line.strip() and not line.lstrip().startswith("|"):
            start = number if not block else start
            block.append(line)
            continue
        if block:
            yield start, " ".join(block)
            block = []
        if not fenced and line.lstrip().startswith("|"):
            yield number, line
    if block:
        yield start, " ".join(block)


def bare_timings(text: str) -> list[tuple[int, str]]:
    """(line, the timing) of every paragraph or table row of ``text`` stating a timing without naming a benchmark."""
    return [(n, m[0]) for n, para in _prose(text) if (m := TIMING.search(para)) and not BENCHMARK.search(para)]


def test_bare_timings_are_refused():
    """No page states a timing without the benchmark that measures it (beyond the known ones still to move)."""
    problems = []
    for page in PAGES:
        name = str(page.relative_to(ROOT))
        found = bare_timings(page.read_text())
        known = KNOWN_BARE_TIMINGS.get(name, 0)
        if len(found) > known:
            problems.append(
                f"{name}: {len(found)} timings with no benchmark named beside them (known {known}): "
                + "; ".join(f"line {n}: {t!r}" for n, t in found)
                + " -- name the benchmark (benchmarks/*.py, mast bench) and its machine in the paragraph"
            )
        elif len(found) < known:
            problems.append(f"{name}: {len(found)} bare timings, KNOWN_BARE_TIMINGS says {known}: lower it")
    assert not problems, "\n".join(problems)


def test_the_timing_check_tells_a_timing_from_simulated_time():
    assert bare_timings("The sweep took 152 s on 2 cores.\n") == [(1, "took 152 s")]
    assert bare_timings("| design | 105 s wall |\n") == [(1, "105 s wall")]
    assert bare_timings("Native real-time factor 105 (`python benchmarks/realtime.py`).\n") == []
    assert bare_timings("A 10 s run with a 1 ms position cycle and a 100 us current cycle.\n") == []
    assert bare_timings("```\ntook 3 s\n```\n") == []


# -- running the blocks -------------------------------------------------------------------------------------
RUN = [b for b in SHELL if b.mark == "run"]


def _apply(block: Block) -> str:
    text = block.text
    for pair in filter(None, (p.strip() for p in block.arg.split(";"))):
        old, sep, new = pair.partition("=>")
        old, new = old.strip(), new.strip()
        assert sep and old, f"{block.where}: replacement {pair!r}: expected OLD => NEW"
        assert old in text, f"{block.where}: replacement {old!r} does not apply: the block changed, update its mark"
        text = text.replace(old, new)
    return text


@pytest.fixture(scope="module")
def scratch(built_native, tmp_path_factory) -> Path:
    """A folder where the documented commands run as in a checkout: build/ is the tests' build."""
    top = tmp_path_factory.mktemp("docs_run")
    work = top / "work"
    work.mkdir()
    (work / "build").symlink_to(built_native, target_is_directory=True)
    # examples/ copied: its configs name the build relative to themselves (../build/ssp/MAST.ssp)
    shutil.copytree(ROOT / "examples", work / "examples", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("docs", "ssp", "tests", "benchmarks"):
        (work / name).symlink_to(ROOT / name, target_is_directory=True)
    if (Path(sys.prefix) / "bin" / "activate").exists():  # `source .venv/bin/activate` (README "First results")
        (work / ".venv").symlink_to(Path(sys.prefix), target_is_directory=True)
    if (ROOT.parent / "shared").is_dir():
        (top / "shared").symlink_to(ROOT.parent / "shared", target_is_directory=True)
    return work


@pytest.mark.parametrize("block", RUN, ids=[b.where for b in RUN])
def test_documented_block_runs(block, scratch, built_native):
    text = _apply(block)
    if "../shared" in text and not (scratch.parent / "shared").exists():
        pytest.skip("needs the measured data in ../shared")
    env = {
        **os.environ,
        "MAST_BUILD": str(built_native),
        "PYTHONPATH": str(ROOT),
        "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")]),
        "MPLBACKEND": "Agg",
    }
    if block.lang == "python":
        script = scratch / f"block_{block.page.stem}_{block.line}.py"
        script.write_text(text + "\n")
        command = [sys.executable, str(script)]
    else:
        command = ["bash", "-euo", "pipefail", "-c", "\n".join(commands(text))]
    proc = subprocess.run(command, cwd=scratch, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, (
        f"{block.where}:\n{text}\nexit {proc.returncode}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    )
