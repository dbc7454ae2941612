"""`rig bench NAME --markdown`: the rows as the table the docs show."""

from orchestrator.cli.bench_cmd import markdown_table


def test_rows_become_one_markdown_table_with_every_column():
    rows = [{"mode": "raw", "error": 8.11667}, {"mode": "corrected", "slots": 2}]
    assert markdown_table(rows).splitlines() == [
        "| mode | error | slots |",
        "|---|---|---|",
        "| raw | 8.117 |  |",
        "| corrected |  | 2 |",
    ]
