"""The thesis's own numbers (Tables 2.5, 2.6, 4.2-4.4) and figure orderings, as shipped data."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pydantic
import pytest

from app.experiments.thesis_data import ThesisDataError, load_thesis_data

ROOT = Path(__file__).resolve().parents[3]
THESIS = ROOT.parent / "shared" / "seed" / "000_b597f14703cb5f83.txt"
TABLES = ["Table 2.5", "Table 2.6", "Table 4.2", "Table 4.3", "Table 4.4"]
FIGURES = [
    "Fig. 2.8",
    "Fig. 2.9",
    "Fig. 3.6",
    "Fig. 3.7",
    "Fig. 3.9",
    "Fig. 4.3",
    "Fig. 4.4",
    "Fig. 4.5",
    "Fig. 5.5",
    "Fig. 5.6",
    "Fig. 5.7",
]


def test_every_table_and_figure_loads() -> None:
    data = load_thesis_data()
    assert sorted(data.tables) == TABLES
    assert sorted(data.figures) == FIGURES
    # Rows: 2 arms × 5 implementation noises (2.5), × 4 training noises (2.6); 5 n × 2 phases
    # (4.2); 3 arms × (mean, sd) + 2 p-values (4.3, 4.4).
    counts = {source: len(table.rows) for source, table in data.tables.items()}
    assert counts == {"Table 2.5": 10, "Table 2.6": 40, "Table 4.2": 10, "Table 4.3": 8,
                      "Table 4.4": 8}  # fmt: skip
    with pytest.raises(pydantic.ValidationError):
        data.tables["Table 2.5"].rows[0].value = 1.0


def test_spot_checks_against_the_thesis_text() -> None:
    """Values typed again by hand from the thesis (text lines 623-630, 654-664, 1029-1038,
    1074-1080, 1090-1096)."""
    data = load_thesis_data()
    t25, t26 = data.tables["Table 2.5"], data.tables["Table 2.6"]
    assert t25.value("Fuzzy GNP-RL", implementation_label="WN_Impl.") == 0.383
    assert t25.value("non-Fuzzy GNP-RL", implementation_sigma=50.0) == 0.401
    assert t25.value("Fuzzy GNP-RL", implementation_label="N_Impl.350") is None  # printed '*'
    assert t26.value("Fuzzy GNP-RL", training_sigma=100.0, implementation_sigma=100.0) == 0.449
    assert t26.value("non-Fuzzy GNP-RL", training_label="N_Train350",
                     implementation_label="N_Impl.150") == 0.313  # fmt: skip
    assert t26.value("Fuzzy GNP-RL", training_sigma=150.0, implementation_sigma=350.0) == 0.078
    assert t26.value("non-Fuzzy GNP-RL", training_sigma=50.0, implementation_sigma=0.0) == 0.372
    t42 = data.tables["Table 4.2"]
    assert t42.value("TSRLch", metric="fitness", schedule_n=pytest.approx(1 / 3)) == 0.545
    assert t42.value("TSRLch", metric="average reward", schedule_n=10.0) == 0.131
    assert t42.value("TSRLch", metric="fitness", schedule_n=1.0) == 0.593
    t43, t44 = data.tables["Table 4.3"], data.tables["Table 4.4"]
    assert t43.value("TSRLch") == 0.158 and t43.value("TSRLch", "sd") == 0.036
    assert t43.value("TSRLco(A)", "p_one_tailed") == 7.25e-06
    assert t43.value("TSRLco(B)", "p_one_tailed") == 3.97e-03
    assert t44.value("TSRLco(B)", "sd") == 0.026 and t44.value("TSRLco(A)") == 0.083
    assert t44.value("TSRLco(B)", "p_one_tailed") == 6.89e-04
    assert {row.condition.implementation_label for row in t44.rows} == {"TSRL/TESTch"}
    assert {row.unit for row in t43.rows} == {"reward/step", "probability"}
    # Orderings the text states.
    fig55 = data.figures["Fig. 5.5"].claims[0]
    assert fig55.order == (("Fuzzy GNP-TSRL (CS)",), ("Fuzzy GNP-TSRL (BS)",), ("Fuzzy GNP-RL",))
    fig29 = data.figures["Fig. 2.9"].claims[1]
    assert fig29.order_of == "training noise"
    assert [g[0] for g in fig29.order] == ["N_Train50", "N_Train100", "N_Train150", "N_Train350"]


def test_every_table_is_a_full_grid() -> None:
    """Each (arm, metric, statistic, condition) appears once: no row typed twice."""
    for table in load_thesis_data().tables.values():
        keys = [(r.arm, r.metric, r.statistic, r.condition) for r in table.rows]
        assert len(set(keys)) == len(keys), table.source


def _normalised(text: str) -> str:
    return re.sub(r"\s+", " ", text).strip()


@pytest.mark.skipif(not THESIS.exists(), reason="the thesis text is not beside the checkout")
def test_quotes_and_captions_are_at_their_lines_in_the_thesis() -> None:
    lines = THESIS.read_text(encoding="utf-8").splitlines()
    data = load_thesis_data()
    for figure in data.figures.values():
        caption_line = _normalised(lines[figure.line - 1])
        assert caption_line.startswith("Figure " + figure.source.removeprefix("Fig. ")), (
            figure.source
        )
        assert _normalised(figure.caption) in caption_line, figure.source
        for claim in figure.claims:
            assert _normalised(claim.quote) in _normalised(lines[claim.line - 1]), (
                f"{figure.source} l. {claim.line}: {claim.quote[:40]}"
            )
    for table in data.tables.values():
        caption_line = lines[table.line - 1]
        assert caption_line.startswith(table.source + ":"), table.source
        # Every printed number of the table is in the table's next 15 lines.
        body = " ".join(lines[table.line : table.line + 15])
        for row in table.rows:
            if row.printed != "*":
                assert row.printed in body, f"{table.source}: {row.printed}"


def test_bad_files_are_named(tmp_path: Path) -> None:
    shipped = ROOT / "app" / "experiments" / "thesis" / "table-4.3.toml"
    text = shipped.read_text(encoding="utf-8")
    (tmp_path / "table-4.3.toml").write_text(text.replace("value = 0.158", "value = 0.185"))
    with pytest.raises(ThesisDataError, match=r"table-4\.3\.toml.*not the printed '0\.158'"):
        load_thesis_data(tmp_path)
    (tmp_path / "table-4.3.toml").unlink()
    (tmp_path / "table-4.4.toml").write_text(text)
    with pytest.raises(ThesisDataError, match=r"holds Table 4\.3; name it table-4\.3\.toml"):
        load_thesis_data(tmp_path)


def test_thesis_data_ships_with_the_package() -> None:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert "experiments/thesis/*.toml" in pyproject["tool"]["setuptools"]["package-data"]["app"]
