"""values.csv, the table a report is written again from (`experiment report --from-values`),
hostile (issue #47): fuzzed, its reader gives results or an ExperimentError; a header-only
table is one line, not a ZeroDivisionError."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_hostile_files import gnp_lab, one_line
from test_readers_fuzz import FUZZ

from app.experiments import harvest
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_shipped
from app.experiments.values import read_values_csv


def test_a_header_only_values_table_is_one_line(tmp_path: Path) -> None:
    values = tmp_path / "values.csv"
    values.write_text("arm,seed,condition,metric,value\n")
    done = gnp_lab(
        "experiment", "report", "ch2-fuzzy-crisp", "--from-values", values,
        "--out", tmp_path / "report", "--runs-dir", tmp_path,
    )  # fmt: skip
    one_line(done, "no values")


@pytest.fixture(scope="module")
def values_template(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Any]:
    spec = load_shipped("ch2-fuzzy-crisp")
    return spec, harvest.collect(spec, "small", tmp_path_factory.mktemp("empty"))


VALUE_ROWS = ["fuzzy,0,,final_best_fitness,0.5", "crisp,1,,final_best_fitness,nan"]


@FUZZ
@given(data=st.data())
def test_values_tables_give_results_or_its_error(
    tmp_path: Path, values_template: tuple[Any, Any], data: st.DataObject
) -> None:
    spec, template = values_template
    rows = data.draw(
        st.lists(
            st.one_of(
                st.sampled_from(VALUE_ROWS),
                st.sampled_from(["", "a,b", "fuzzy,-1,,final_best_fitness,1", "x" * 200_000]),
                st.sampled_from(["fuzzy,1e999,,final_best_fitness,1", "fuzzy,0,,final,inf"]),
            ),
            max_size=4,
        )
    )
    path = tmp_path / "values.csv"
    path.write_text("\n".join(["arm,seed,condition,metric,value", *rows]) + "\n")
    try:
        results = read_values_csv(path, spec, template)
        assert len(results.seeds) >= 1
    except ExperimentError:
        pass
