"""The thesis's own numbers and orderings, as validated, frozen data.

`app/experiments/thesis/*.toml` holds one file per table (Tables 2.5, 2.6, 4.2, 4.3, 4.4,
transcribed exactly) and one per figure whose text gives only an ordering (Figs. 2.8, 2.9, 3.6,
3.7, 3.9, 4.3-4.5, 5.5-5.7: the ordering the text states, with the sentence and its line in the
thesis's text). Names follow the thesis (arms "Fuzzy GNP-RL", "TSRLch", ...; conditions
"N_Impl.50", "TSRL/TESTco", ...), so experiment specs can be joined to them later.

A table row is one printed number: its arm, metric, statistic (mean, sd, one-tailed p), the
condition it was measured under, the value, the exact string printed (`*` where the thesis prints
no value) and its unit. A figure claim orders arms (or conditions) from highest to lowest; an item
of `order` may be a group whose members the text does not order among themselves.
"""

from __future__ import annotations

import math
import re
import tomllib
from functools import cache
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from app.settings.loading import describe_problems

Statistic = Literal["mean", "sd", "p_one_tailed"]
Relation = Literal["higher", "converges faster", "as large as", "better"]
OrderOf = Literal["arm", "training noise", "implementation schedule", "broken sensors", "phase"]


class ThesisDataError(ValueError):
    """A thesis data file is missing, malformed or inconsistent; the message names it."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Condition(_Frozen):
    """What a number or a claim was measured under. Unset = the thesis does not say or it does
    not apply. Steps and generations are counted from 1, as the thesis counts them."""

    phase: Literal["training", "implementation"]
    training_sigma: float | None = Field(default=None, ge=0, description="training noise σ")
    implementation_sigma: float | None = Field(
        default=None, ge=0, description="implementation noise σ"
    )
    training_label: str | None = Field(default=None, description="e.g. WN_Train, N_Train50")
    implementation_label: str | None = Field(
        default=None, description="e.g. WN_Impl., N_Impl.50, TSRL/TESTco, TSRL/TESTch"
    )
    implementation_schedule: Literal["fixed", "changing"] | None = Field(
        default=None, description="ε/α in the implementation: fixed, or Eq. 4.3-4.4"
    )
    schedule_n: float | None = Field(default=None, gt=0, description="n of Eq. 4.1-4.4")
    broken_sensors: tuple[int, ...] | None = Field(
        default=None, description="numbers of sensors that break (0 = none) the value covers"
    )
    fault_step: int | None = Field(default=None, ge=0, description="step the sensors break at")
    training_steps: int | None = Field(default=None, ge=1, description="training life time T")
    implementation_steps: int | None = Field(
        default=None, ge=1, description="implementation life time T"
    )
    generation: int | None = Field(default=None, ge=1, description="generation read at")
    from_step: int | None = Field(default=None, ge=1, description="first step averaged")
    to_step: int | None = Field(default=None, ge=1, description="last step averaged")


class TableRow(_Frozen):
    """One number printed in a table."""

    source: str
    arm: str = Field(min_length=1, description="the method/arm as the thesis names it")
    metric: str = Field(min_length=1, description="e.g. average reward, fitness")
    statistic: Statistic = "mean"
    condition: Condition
    value: float | None = Field(
        default=None, description="the number; unset where the thesis prints *"
    )
    printed: str = Field(min_length=1, description="the number exactly as printed")
    unit: str = Field(min_length=1)
    note: str | None = None

    @model_validator(mode="after")
    def _value_is_printed(self) -> TableRow:
        if self.printed == "*":
            if self.value is not None:
                raise ValueError("a '*' in the thesis has no value")
        elif self.value is None or not math.isclose(
            float(self.printed), self.value, rel_tol=0, abs_tol=0
        ):
            raise ValueError(f"value {self.value} is not the printed {self.printed!r}")
        return self


class ThesisTable(_Frozen):
    """A table of the thesis, transcribed."""

    kind: Literal["table"]
    source: str = Field(pattern=r"^Table \d\.\d+$")
    caption: str = Field(min_length=1)
    line: int = Field(ge=1, description="line of the caption in the thesis's text")
    averaged_over: str | None = None
    note: str | None = None
    rows: tuple[TableRow, ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _rows_cite_the_table(self) -> ThesisTable:
        for row in self.rows:
            if row.source != self.source:
                raise ValueError(f"row {row.arm!r} cites {row.source!r}, not {self.source!r}")
        return self

    def value(self, arm: str, statistic: Statistic = "mean", **condition: object) -> float | None:
        """The one value of `arm` whose condition has the given fields (e.g. metric=...)."""
        metric = condition.pop("metric", None)
        hits = [
            row
            for row in self.rows
            if row.arm == arm
            and row.statistic == statistic
            and (metric is None or row.metric == metric)
            and all(getattr(row.condition, k) == v for k, v in condition.items())
        ]
        if len(hits) != 1:
            raise ThesisDataError(
                f"{self.source}: {len(hits)} rows for {arm!r} {statistic} {condition}"
            )
        return hits[0].value


class Claim(_Frozen):
    """An ordering a figure's text states: `order` from highest to lowest by `relation`."""

    source: str
    line: int = Field(ge=1, description="line of the sentence in the thesis's text")
    quote: str = Field(min_length=1, description="the thesis's sentence, verbatim")
    statement: str = Field(min_length=1, description="the claim in our words")
    metric: str = Field(min_length=1)
    relation: Relation
    order_of: OrderOf = "arm"
    order: tuple[tuple[str, ...], ...] = Field(min_length=2)
    arms: tuple[str, ...] = Field(
        default=(), description="the arms an ordering of conditions holds for"
    )
    condition: Condition
    note: str | None = None

    @field_validator("order", mode="before")
    @classmethod
    def _groups(cls, order: object) -> object:
        if isinstance(order, list | tuple):
            return [[item] if isinstance(item, str) else item for item in order]
        return order

    @model_validator(mode="after")
    def _distinct(self) -> Claim:
        items = [item for group in self.order for item in group]
        if len(set(items)) != len(items) or any(not group for group in self.order):
            raise ValueError(f"order must list distinct items in non-empty groups: {items}")
        return self


class ThesisFigure(_Frozen):
    """A figure of the thesis (not in its text) and the orderings its text states."""

    kind: Literal["figure"]
    source: str = Field(pattern=r"^Fig\. \d\.\d+$")
    caption: str = Field(min_length=1)
    line: int = Field(ge=1, description="line of the caption in the thesis's text")
    claims: tuple[Claim, ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _claims_cite_the_figure(self) -> ThesisFigure:
        for claim in self.claims:
            if claim.source != self.source:
                raise ValueError(f"a claim cites {claim.source!r}, not {self.source!r}")
        return self


class ThesisData(_Frozen):
    """Every table and figure, keyed by its source ("Table 2.5", "Fig. 3.7")."""

    tables: dict[str, ThesisTable]
    figures: dict[str, ThesisFigure]


def _expected_name(source: str) -> str:
    match = re.fullmatch(r"(Table|Fig\.) (\d\.\d+)", source)
    if not match:
        raise ThesisDataError(f"not a table or figure: {source!r}")
    return f"{'table' if match[1] == 'Table' else 'fig'}-{match[2]}.toml"


def _folder() -> Traversable:
    return resources.files("app.experiments").joinpath("thesis")


def load_thesis_data(folder: str | Path | None = None) -> ThesisData:
    """Read and validate every `*.toml` in `folder` (default: the shipped thesis data).

    Raises:
        ThesisDataError: naming the file and every problem in it.
    """
    if folder is None:
        return _shipped()
    return _load(Path(folder))


@cache
def _shipped() -> ThesisData:
    return _load(_folder())


def _load(folder: Traversable | Path) -> ThesisData:
    tables: dict[str, ThesisTable] = {}
    figures: dict[str, ThesisFigure] = {}
    files = sorted((f for f in folder.iterdir() if f.name.endswith(".toml")), key=lambda f: f.name)
    if not files:
        raise ThesisDataError(f"no thesis data files in {folder}")
    for file in files:
        try:
            raw = tomllib.loads(file.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as error:
            raise ThesisDataError(f"{file.name} is not valid TOML: {error}") from None
        try:
            item: ThesisTable | ThesisFigure
            if raw.get("kind") == "table":
                item = ThesisTable.model_validate(raw)
            else:
                item = ThesisFigure.model_validate(raw)
        except ValidationError as error:
            raise ThesisDataError(f"{file.name}: {describe_problems(error)}") from None
        if file.name != _expected_name(item.source):
            raise ThesisDataError(
                f"{file.name} holds {item.source}; name it {_expected_name(item.source)}"
            )
        if isinstance(item, ThesisTable):
            tables[item.source] = item
        else:
            figures[item.source] = item
    return ThesisData(tables=tables, figures=figures)
