"""The reader of the documentation's message tables (tests/message_tables.py) against hand-written rows."""

from __future__ import annotations

from message_tables import code_spans, documented_messages, documented_mismatches


def test_a_message_holding_backticks_is_read_from_a_longer_span():
    assert code_spans("`a` then `` b `c` d `` and ```e``f```") == ["a", "b `c` d", "e``f"]
    assert code_spans("no span, a lone ` tick") == []
    assert code_spans("`  `") == ["  "]


def test_a_drifted_second_message_is_a_mismatch():
    """Every quoted message of a row is compared, not only its first; a row that quotes fewer or more fails."""
    page = {"p": ["a.csv: one ...", "b.csv: two ..."]}
    assert documented_mismatches(page, {"p": ["a.csv: one x", "b.csv: two y"]}) == []
    assert documented_mismatches(page, {"p": ["a.csv: one x", "b.csv: three y"]}) == [
        "p: message 2: the page says 'b.csv: two ...', the code 'b.csv: three y'"
    ]
    assert documented_mismatches(page, {"p": ["a.csv: one x"]})
    assert documented_mismatches({"q": ["DIR: no `x`"]}, {"q": ["/tmp/run: no `x`"]}) == []
    assert documented_mismatches({"q": ["DIR: no `x`"]}, {"q": ["/tmp/run: no x"]})


def test_a_table_is_read_under_its_heading_to_the_blank_line(tmp_path):
    page = tmp_path / "p.md"
    page.write_text(
        "# Other\n\n| a | b |\n|---|---|\n| x | `not this` |\n\n## Bad input\n\nText.\n\n| input | message |\n"
        "|---|---|\n| no file | `` DIR: no `f` `` (or `DIR: no g`) |\n| a bad row | `one ...` |\n"
        "\nAfter.\n| z | `z` |\n"
    )
    assert documented_messages(page, "## Bad input") == {
        "no file": ["DIR: no `f`", "DIR: no g"],
        "a bad row": ["one ..."],
    }
