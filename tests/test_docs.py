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
from docs_figures import figures

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


def test_one_meaning_per_option_name_every_out_is_a_folder():
    """`--out` (and `--truth-out`) name a folder in every subcommand, checked as one before anything runs; the former
    file spellings (`animate --out PAGE.html`, `synthesize --truth FILE`) are refused, naming the new form."""
    files = [
        f"mast {name} {'/'.join(a.option_strings)}"
        for name, sub in _subparsers(_full_parser()).items()
        for a in sub._actions
        if any(o.endswith("-out") or o == "--out" for o in a.option_strings)
        and a.help is not argparse.SUPPRESS
        and a.type not in (cli.folder, cli.animate_folder)
    ]
    assert not files, f"output options that do not name a folder: {files}"
    for argv, says in (
        (["animate", "run", "--out", "page.html"], "mast animate RUN_DIR --out DIR writes DIR/motion.html"),
        (["synthesize", "--out", "d", "--truth", "t.json"], "--truth was renamed: --truth-out DIR"),
    ):
        err = io.StringIO()
        with contextlib.redirect_stderr(err), pytest.raises(SystemExit) as stop:
            cli.main(argv)
        assert stop.value.code == 2 and says in err.getvalue(), err.getvalue()


# -- figures ------------------------------------------------------------------------------------------------
def test_every_marked_figure_is_known():
    problems = [p for p in figures.check({}) if "is not in docs/figures.py" in p]
    assert not problems, "\n".join(problems)


def test_marked_figures_of_the_system_files_and_designs_agree():
    """The gains MAST.ssd binds (docs/controller.md), the designs' margins at home (docs/mechanism.md), the drive
    ratings (docs/sizing.md), the FMUs mast build writes and the archive limits (README, docs/interfaces.md), the
    inertias of paper Fig. 10's argument (docs/designs/README.md), the tests `mast synthesize` writes by default
    (README)."""
    problems = figures.check(
        {
            "ssd": figures.source_ssd(),
            "designs": figures.source_designs(),
            "ratings": figures.source_ratings(),
            "build": figures.source_build(),
            "inertias": figures.source_inertias(),
            "defaults": figures.source_defaults(),
        }
    )
    assert not problems, "\n".join(problems)


def test_marked_workspace_figures_agree():
    """The designs' workspaces: docs/workspace.md (default grid), README "First results" (compare's quick grid)."""
    problems = figures.check(
        {"workspace": figures.source_workspace(), "workspace_quick": figures.source_workspace(quick=True)}
    )
    assert not problems, "\n".join(problems)


def test_marked_sizing_figures_agree(built_native):
    """docs/sizing.md: the drives of the default run and of the paper's 10 Hz z test against their ratings."""
    problems = figures.check({"sizing": figures.source_sizing(built_native / "ssp" / "MAST.ssp")})
    assert not problems, "\n".join(problems)


@pytest.mark.skipif(not figures.EMPS_RECORD.exists(), reason=f"{figures.EMPS_RECORD} not present")
def test_marked_emps_replay_figures_agree():
    """docs/emps.md: `mast replay` of the EMPS record with the published estimates and with the nominal model."""
    problems = figures.check({"emps": figures.source_emps()})
    assert not problems, "\n".join(problems)


def test_marked_hexapod_figures_agree():
    """docs/designs/6ups.md: the 6-UPS's and 6-PUS's margins, static forces and mass matrices at home, their
    workspaces on a coarse grid; docs/designs/3rps.md: the 3-RPS's parasitic motion, statics, mass matrix, margins
    and workspaces."""
    problems = figures.check(
        {"hexapod": figures.source_hexapod(), "hexapod_pus": figures.source_hexapod_pus(), "rps": figures.source_rps()}
    )
    assert not problems, "\n".join(problems)


def test_a_marker_may_state_its_figure_to_other_digits(tmp_path):
    """``<!-- figure KEY:SPEC -->``: the page states KEY's value written with ``{:SPEC}``; check compares that, write
    keeps the specification."""
    page = tmp_path / "p.md"
    page.write_text("z <!-- figure geometry.z_home_m:.3f -->0.405<!-- /figure --> m\n")
    values = {"geometry": {"z_home_m": 0.405147}}
    assert figures.check(values, [page]) == []
    assert figures.check({"geometry": {"z_home_m": 0.4062}}, [page])  # 0.406 != 0.405, beyond the key's 0 tolerance
    figures.write({"geometry": {"z_home_m": 0.4062}}, [page])
    assert page.read_text() == "z <!-- figure geometry.z_home_m:.3f -->0.406<!-- /figure --> m\n"


def test_every_figure_source_is_checked_by_a_test():
    """A source added to docs/figures.py is compared with the pages somewhere (here, tests/test_reproduce.py or the
    tests named beside them)."""
    checked = {
        "ssd",
        "designs",
        "workspace",
        "workspace_quick",
        "reproduce",
        "ratings",
        "build",
        "inertias",
        "defaults",
        "sizing",
        "emps",
        "emps_diagnose",  # tests/test_emps.py, on the diagnosis it runs
        "hexapod",
        "hexapod_pus",
        "rps",
        "hexapod_run",  # tests/test_hexapod_system.py, on the run it makes
        "diagnose_hexapod",  # tests/test_hexapod_diagnosis.py
        "animate",  # tests/test_animate.py
        "controllers_short",  # tests/test_controllers.py
        "designs_short",  # tests/test_compare.py
        *(f"diagnose_{case}" for case in figures.DIAGNOSE_CASES),  # tests/test_diagnose.py
        # tests/test_diagnose_unseen.py
        *(f"diagnose_{case}" for case in (*figures.DIAGNOSE_HEAVIER_LIGHTER, *figures.DIAGNOSE_ONE_AXIS_AND_DRIVE)),
        *(f"diagnose_{case}" for case in (*figures.DIAGNOSE_LAGS, *figures.DIAGNOSE_PER_AXIS)),  # test_diagnose_split
        *(f"diagnose_{case}" for case in figures.DIAGNOSE_BACKLASH),  # tests/test_diagnose_backlash.py
        "diagnose_model",
        "sets",
        "actuator",
        "geometry",
        "examples",
        "design_pages",
        "workspace_payload",
        "native",
        "emps_pulses",  # tests/test_emps.py, on the diagnosis it runs
    }
    assert set(figures.SOURCES) == checked, f"sources no test compares: {set(figures.SOURCES) - checked}"


def test_marked_figures_of_the_parameter_sets_actuator_geometry_and_examples_agree(built_native):
    """The parameter sets' values the pages restate (docs/actuator.md, controller.md, ...), what the actuator's
    relations give for them (docs/actuator.md), the 3PRS's home pose (docs/geometry.md, interfaces.md), the cases
    the example batch configs expand to and the controller comparison's sine tests (docs/batch.md, controller.md)."""
    problems = figures.check(
        {
            "sets": figures.source_sets(),
            "actuator": figures.source_actuator(),
            "geometry": figures.source_geometry(),
            "examples": figures.source_examples(built_native),
        }
    )
    assert not problems, "\n".join(problems)


def test_the_headline_figures_are_marked():
    """The figures a change most likely moves are generated into the pages, not typed."""
    text = (ROOT / "docs" / "reproduction.md").read_text()
    for key in ("reproduce.predictions_within", "reproduce.predictions", "reproduce.phase_10Hz_z"):
        assert f"<!-- figure {key} -->" in text, key


def test_marked_diagnose_model_figures_agree():
    """docs/diagnose.md: the documented drive its tables compare with (ssp/MAST.ssd's controller), the transmission's
    stiffness and mode, the force and mass the drive holds at its current limit, the hexapod library's size."""
    problems = figures.check({"ssd": figures.source_ssd(), "diagnose_model": figures.source_diagnose_model()})
    assert not problems, "\n".join(problems)


def test_marked_design_page_and_payload_workspace_figures_agree():
    """docs/designs/*.md and docs/mechanism.md: the 3PRS designs at home, their forces' split on a 5 Hz sine, the 120°
    layout's parasitic motion; docs/workspace.md: the T design's workspace with a 5 kg payload (default grid)."""
    problems = figures.check(
        {"design_pages": figures.source_design_pages(), "workspace_payload": figures.source_workspace_payload()}
    )
    assert not problems, "\n".join(problems)


def test_marked_native_figures_agree(built_native):
    """docs/native.md: the generated C of the native FMUs the tests built, the actuator's kernels, what the
    parameters alone fix in the 3PRS's traced functions."""
    problems = figures.check({"native": figures.source_native(built_native)})
    assert not problems, "\n".join(problems)


# -- timings ------------------------------------------------------------------------------------------------
# A timing (wall or CPU time of a command, a real-time factor, "x times faster", cases per second) depends on the
# machine and its load: a page states one only with the command that measured it (a benchmark: benchmarks/*.py, `mast
# bench`, `make bench...`; or the command timed, `` `time mast ...` ``) and the machine it ran on (the project's 2-core
# development VM, an AMD EPYC), both in the same paragraph or table row (a table row: or in the paragraph right before
# its table, the table's caption). Every duration in seconds, minutes or hours is taken for a timing ("(102 s)" in a
# table cell too) unless the words beside it say it is simulated time or a model's constant: "a 10 s run", "3 s of
# motion", "at t = 1.2 s", "z at 2 Hz, 0.4 s", "time constants 42.8 s"; durations in ms and us are a model's cycles.
_SECONDS = r"\d+(?:\.\d+)?\s*(?:s|ms|min|minutes?|seconds?|h|hours?)\b"
TIMING = re.compile(
    r"\b(?:takes?|took|taking|runs? in|ran in|wall(?:[- ]clock| time)?|elapsed)\b[^.;|]{0,30}?"
    + _SECONDS
    + r"|"
    + _SECONDS
    + r"[^.;|]{0,25}?\b(?:on (?:\d+|two|one|a|this|the) (?:cores?|CPUs?|machine|laptop)|wall|"
    r"per (?:case|run|simulation|co-simulation))\b"
    r"|real[- ]time factor[^.;|]{0,20}?\d|\d+(?:\.\d+)?\s*(?:x|times) (?:faster|slower|quicker|cheaper)"
    r"|\d+(?:\.\d+)?\s*(?:cases|simulations|runs|steps)/s\b",
    re.I,
)
DURATION = re.compile(
    r"(?<![\w.\-])(?:\d+(?:\.\d+)?(?:\s*s)?\s*(?:-|to|and|/|,)\s*)*\d+(?:\.\d+)?\s*(?:s|seconds?|min|minutes?|h|hours?)\b(?!/)"
)
#: the words right after a duration that make it simulated time ("a 10 s run", "1 s simulated", "3 s of motion")
SIMULATED_AFTER = re.compile(
    r"^\W{0,3}(?:of\s+(?!CPU|wall|gcc|compil)|simulated|runs?\b|tests?\b|records?\b|cycles?\b|windows?\b|sine|"
    r"co-simulation|plus\b|long\b|apart\b|each\b|per\s+(?:test|case)|plan\b|minus\b|analysed)",
    re.I,
)
#: the words right before a duration that make it simulated time or a constant ("at t = 1.2 s", "z at 2 Hz, 0.4 s")
SIMULATED_BEFORE = re.compile(
    r"(?:\bt\s*(?:=|>=|<=|<|>)|\bat|\bafter|\bevery|\bfor|\bover|\bfrom|\bstop(?:[- ]time)?|settl\w*|period\w*|"
    r"\bfirst|\blast|\bwithin|\bruns?|\bof|\buntil|\bbefore|\blasts?|\bduration|\bthis|\bon|\bnearest|"
    r"constants?|\bleast|min\(|records?\s*\(|Hz,|mm,|deg,|°,|samples,|`\w*\.ssp`,)"
    r"\s*(?:about|the|a|its|only)?\s*$",
    re.I,
)
MEASURED_BY = re.compile(r"benchmarks/\w+\.py|mast bench|make bench|`time [^`]+`")
MACHINE = re.compile(r"development (?:VM|machine)|AMD EPYC|shared 2-core machine")


def _prose(text: str) -> Iterator[tuple[int, str, str]]:
    """(first line, text, context) of every paragraph and table row outside fenced blocks: a paragraph's context is
    itself, a table row's the row and the paragraph right before its table (the table's caption)."""
    block: list[str] = []
    start, fenced, caption = 1, False, ""
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and line.strip() and not line.lstrip().startswith("|"):
            start = number if not block else start
            block.append(line)
            continue
        if block:
            caption = " ".join(block)
            yield start, caption, caption
            block = []
        if not fenced and line.lstrip().startswith("|"):
            yield number, line, caption + " " + line
        elif not line.strip() or fenced:
            caption = caption if not line.strip() and not fenced else ""
    if block:
        yield start, " ".join(block), " ".join(block)


def _durations(text: str) -> Iterator[re.Match]:
    """The durations of ``text`` that are not marked simulated time or a constant by the words beside them."""
    for match in DURATION.finditer(text):
        if not (
            SIMULATED_AFTER.search(text[match.end() : match.end() + 30])
            or SIMULATED_BEFORE.search(text[max(0, match.start() - 25) : match.start()])
        ):
            yield match


def bare_timings(text: str) -> list[tuple[int, str]]:
    """(line, the timing) of every paragraph or table row of ``text`` stating a timing (a timing's wording, or any
    duration not marked simulated) without naming both the command that measured it and the machine."""
    found = []
    for n, para, context in _prose(text):
        if MEASURED_BY.search(context) and MACHINE.search(context):
            continue
        # inline code (`--stop-time 3`, `mast run ... 0.5`) and markers are not prose
        prose = re.sub(r"<!--.*?-->", "", re.sub(r"`[^`]*`", lambda m: "`" + "x" * (len(m[0]) - 2) + "`", para))
        if m := TIMING.search(prose) or next(_durations(prose), None):
            found.append((n, m[0]))
    return found


def test_bare_timings_are_refused():
    """No page states a timing without the command that measured it and the machine it ran on."""
    problems = [f"{page.relative_to(ROOT)}:{n}: {t!r}" for page in PAGES for n, t in bare_timings(page.read_text())]
    assert not problems, (
        "timings stated without the command that measured them (benchmarks/*.py, mast bench, `time COMMAND`) and "
        "the machine (the 2-core development VM, AMD EPYC) in the same paragraph or table row: name both, or "
        "state the cost as a count (simulations, steps), or drop it:\n" + "\n".join(problems)
    )


def test_the_timing_check_tells_a_timing_from_simulated_time():
    assert bare_timings("The sweep took 152 s on 2 cores.\n") == [(1, "took 152 s")]
    assert bare_timings("| design | 105 s wall |\n") == [(1, "105 s wall")]
    vm = "on the 2-core development VM (AMD EPYC)"
    assert bare_timings(f"Native real-time factor 105 (`python benchmarks/realtime.py`, {vm}).\n") == []
    assert bare_timings(f"It took 152 s (`time mast reproduce`, {vm}).\n") == []
    assert bare_timings("It took 152 s (`time mast reproduce`).\n") == [(1, "took 152 s")]  # which machine?
    assert bare_timings(f"It took 152 s {vm}.\n") == [(1, "took 152 s")]  # measured how?
    assert bare_timings("A 10 s run with a 1 ms position cycle and a 100 us current cycle.\n") == []
    assert bare_timings("```\ntook 3 s\n```\n") == []
    # any duration is a timing unless its words make it simulated time or a constant
    assert bare_timings("| design | (102 s) |\n") == [(1, "102 s")]
    assert bare_timings("| hidden | named | 199 s, 140 |\n") == [(1, "199 s")]
    assert bare_timings("Cost: 16 simulations, 84 s.\n") == [(1, "84 s")]
    assert bare_timings("About 5-6 s of CPU per design.\n") == [(1, "5-6 s")]
    assert bare_timings(f"Measured (`time mast compare`, {vm}):\n\n| design | wall |\n|---|---|\n| T | 105 s |\n") == []
    assert bare_timings("Measured by hand:\n\n| design | wall |\n|---|---|\n| T | 105 s |\n") == [(5, "105 s")]
    for simulated in (
        "A 10 s run.",
        "3 s of motion.",
        "The gap after t = 1.2 s.",
        "The z sine (10 mm at 1 Hz, 3 s).",
        "Time constants 42.8 s and 809 s.",
        "Each test runs 1 s plus two periods.",
        "| stepping | (1 s simulated) |",
    ):
        assert bare_timings(simulated + "\n") == [], simulated


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


# -- links ----------------------------------------------------------------------------------------------------------
LINK = re.compile(r"(?<!!)\[[^\]]*\]\((?P<target>[^)\s]+)\)|!\[[^\]]*\]\((?P<image>[^)\s]+)\)")


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, markup and punctuation dropped (hyphens and underscores kept),
    spaces as hyphens."""
    text = re.sub(r"<!--.*?-->", "", heading).strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of ``page``'s headings (outside code blocks); a repeated heading gets -1, -2, ... as on GitHub."""
    found: set[str] = set()
    fenced = False
    for line in page.read_text().splitlines():
        if FENCE.match(line):
            fenced = not fenced
        elif not fenced and line.startswith("#"):
            base = slug(line.lstrip("#"))
            name, k = base, 0
            while name in found:
                k += 1
                name = f"{base}-{k}"
            found.add(name)
    return found


def test_slug_is_githubs():
    assert slug(" Speed") == "speed"
    assert slug(" `mast diagnose`: name what the model is missing") == "mast-diagnose-name-what-the-model-is-missing"
    assert slug(" Tool by tool (ecos, libcosim)") == "tool-by-tool-ecos-libcosim"


def test_every_relative_link_and_anchor_resolves():
    """A link of README.md or docs/ to a file of the repository names a file that exists, and its #anchor a heading
    of that file (a renamed heading or a moved page fails here, not for a reader)."""
    broken = []
    for page in PAGES:
        for number, line in enumerate(page.read_text().splitlines(), 1):
            for match in LINK.finditer(line):
                target = match["target"] or match["image"]
                if re.match(r"[a-z]+:", target):  # http:, https:, mailto:
                    continue
                path, _, anchor = target.partition("#")
                file = (page.parent / path).resolve() if path else page
                where = f"{page.relative_to(ROOT)}:{number}: {target}"
                if not file.exists():
                    broken.append(f"{where}: no file {file.relative_to(ROOT) if file.is_relative_to(ROOT) else file}")
                elif anchor and file.suffix == ".md" and anchor not in anchors(file):
                    broken.append(f"{where}: no heading with the anchor #{anchor}")
    assert not broken, "\n".join(broken)
