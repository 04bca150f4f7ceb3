"""The reports' markdown tables and cells (``sb3_huri.experiments.markdown``)."""

import math

import pytest

from sb3_huri.experiments.markdown import interval_cell, mean_cell, table, table_head, table_row


def test_a_table_is_its_header_a_separator_and_a_line_per_row() -> None:
    assert table(["method", "seeds", "return"], [["`huri`", 3, "1.5"], ["`ppo`", 2, "-"]]) == [
        "| method | seeds | return |",
        "|---|---|---|",
        "| `huri` | 3 | 1.5 |",
        "| `ppo` | 2 | - |",
    ]
    assert table(["a"], []) == table_head(["a"]) == ["| a |", "|---|"]
    assert table_row(["x", ""]) == "| x |  |"


def test_a_row_of_another_width_than_the_header_is_refused() -> None:
    with pytest.raises(ValueError, match="2 cells, its header 3 columns"):
        table(["a", "b", "c"], [["1", "2", "3"], ["1", "2"]])


def test_cells_write_a_mean_and_an_interval() -> None:
    assert mean_cell((0.5, 0.125, 3)) == "0.50 ± 0.12"
    assert mean_cell((0.5, math.inf, 1), 1) == "0.5"
    assert mean_cell((math.nan, math.nan, 0)) == "-"
    assert interval_cell(0.25, -0.5, 1.0, "+.3f") == "+0.250 [-0.500, +1.000]"
    assert interval_cell(1857.04, 1787.66, 1923.81, ".1f") == "1857.0 [1787.7, 1923.8]"
