"""The thesis's headline questions: each answered by one claim a shipped experiment declares.

The questions live in `questions.toml` beside this module (what each asks, which claim answers
it, which others bear on it). The page's first table, "The answers", is written from them and
the committed reports: a question's verdict is its answering claim's verdict, nothing pooled.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.experiments.results import VERDICTS
from app.experiments.spec import ExperimentError, load_shipped

QUESTIONS_FILE = "questions.toml"


class Question(BaseModel):
    """One headline question of the thesis and the declared claim that answers it."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    text: str = Field(min_length=1, description="the question, as a reader would ask it")
    experiment: str = Field(description="the shipped experiment that asks it")
    claim: str = Field(description="the name of the claim whose verdict answers it")
    also: tuple[str, ...] = Field(default=(), description="the experiment's other claims on it")


class Questions(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    question: tuple[Question, ...]


def load_questions() -> tuple[Question, ...]:
    """The shipped questions, each claim checked against its experiment's spec."""
    text = resources.files("app.experiments").joinpath(QUESTIONS_FILE).read_text("utf-8")
    try:
        questions = Questions.model_validate(tomllib.loads(text)).question
    except (tomllib.TOMLDecodeError, ValidationError) as error:
        raise ExperimentError(f"{QUESTIONS_FILE}: {error}") from None
    for question in questions:
        names = {c.name for c in load_shipped(question.experiment).comparisons}
        unknown = [c for c in (question.claim, *question.also) if c not in names]
        if unknown:
            raise ExperimentError(
                f"{QUESTIONS_FILE}: {question.experiment} has no claim {', '.join(unknown)}"
            )
    return questions


def _claims(report: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    return {c["name"]: c for c in report["comparisons"]} if report else {}


def ran(comparison: dict[str, Any]) -> bool:
    """Whether a claim has values on both sides (a claim added after its report's runs has none)."""
    return all(comparison["runs"])


def runs_text(comparison: dict[str, Any]) -> str:
    """'20 + 20 runs' (two arms), '20 runs' (one arm, paired by seed)."""
    a, b = comparison["runs"]
    return f"{a} runs" if comparison["paired"] and a == b else f"{a} + {b} runs"


def answer(comparison: dict[str, Any] | None) -> str:
    """'**held** (20 + 20 runs)': the verdict and the runs behind it; 'not run' without one."""
    if comparison is None or not ran(comparison):
        return "not run"
    return f"**{comparison['verdict']}** ({runs_text(comparison)})"


def measured(comparison: dict[str, Any] | None) -> str:
    """'Δ +0.013 [−0.004, +0.030]' of the answering claim, or '—'."""
    if comparison is None or comparison["difference"] is None:
        return "—"
    interval = comparison["interval"]
    text = f"Δ {comparison['difference']:+.3f}"
    if interval["low"] is not None:
        text += f" [{interval['low']:+.3f}, {interval['high']:+.3f}]"
    return text


def tally(comparisons: list[dict[str, Any]]) -> str:
    """'2 held, 3 undecided, 1 not run'; '—' for no claims."""
    counts: dict[str, int] = {
        v: sum(ran(c) and c["verdict"] == v for c in comparisons) for v in VERDICTS
    }
    counts["not run"] = sum(not ran(c) for c in comparisons)
    return ", ".join(f"{n} {v}" for v, n in counts.items() if n) or "—"


def answers_table(reports: dict[tuple[str, str], dict[str, Any]]) -> str:
    """The headline table: a row per question, its verdict at `small` and at `thesis` scale."""
    out = [
        "| question | experiment: answering claim | small | thesis | small: Δ [interval] "
        "| small: the other claims on it |",
        "|---|---|---|---|---|---|",
    ]
    for question in load_questions():
        small = _claims(reports.get((question.experiment, "small")))
        thesis = _claims(reports.get((question.experiment, "thesis")))
        others = [small[name] for name in question.also if name in small]
        thesis_cell = answer(thesis.get(question.claim)) if thesis else "—"
        row = [
            question.text,
            f"{question.experiment}: `{question.claim}`",
            answer(small.get(question.claim)),
            thesis_cell,
            measured(small.get(question.claim)),
            tally(others),
        ]
        out.append("| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |")
    return "\n".join(out) + "\n"
