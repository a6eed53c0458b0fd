"""The thesis's headline questions: each answered by one claim a shipped experiment declares.

The questions live in `questions.toml` beside this module (what each asks, which claim answers
it, which others bear on it). The page's first table, "The answers", is written from them and
the committed reports: a question's verdict is its answering claim's verdict, nothing pooled.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from typing import Any, NamedTuple

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.experiments.results import VERDICTS
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_shipped, shipped_names

QUESTIONS_FILE = "questions.toml"
DECISIVE = "-decisive"  # the pre-registered experiment asking the same question: NAME-decisive


class Question(BaseModel):
    """One headline question of the thesis and the declared claim that answers it."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    text: str = Field(min_length=1, description="the question, as a reader would ask it")
    experiment: str = Field(description="the shipped experiment that asks it")
    claim: str = Field(description="the name of the claim whose verdict answers it")
    also: tuple[str, ...] = Field(default=(), description="the experiment's other claims on it")
    decisive: str | None = Field(
        None,
        description="'experiment: claim' of the decisive (pre-registered, thesis-scale) design "
        "that asks it, where its names differ from this question's (default: the claim of the "
        "same name in EXPERIMENT-decisive, if it is shipped)",
    )

    def decisive_claim(self) -> tuple[str, str] | None:
        """(experiment, claim) of the decisive design asking this question, if one does."""
        if self.decisive is not None:
            name, _, claim = self.decisive.partition(":")
            return name.strip(), claim.strip()
        name = self.experiment + DECISIVE
        if name in shipped_names() and any(
            c.name == self.claim for c in load_shipped(name).comparisons
        ):
            return name, self.claim
        return None


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
        if question.decisive is not None:
            name, claim = question.decisive_claim() or ("", "")
            spec = load_shipped(name)
            if spec.design is None or claim not in {c.name for c in spec.comparisons}:
                raise ExperimentError(
                    f"{QUESTIONS_FILE}: {question.decisive!r} is not a decisive design's claim"
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


def verdict_words(comparison: dict[str, Any]) -> str:
    """'**held**', or '**ruled out**, post hoc' for a verdict judged on data seen before its
    claim or margin was declared."""
    late = ", post hoc" if comparison.get("post_hoc") else ""
    return f"**{comparison['verdict']}**{late}"


def answer(comparison: dict[str, Any] | None) -> str:
    """'**held** (20 + 20 runs)': the verdict and the runs behind it; 'not run' without one."""
    if comparison is None or not ran(comparison):
        return "not run"
    return f"{verdict_words(comparison)} ({runs_text(comparison)})"


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
    """'2 held, 3 undecided; post hoc: 1 ruled out; 1 not run; 4 exploratory': pre-registered
    verdicts first, post hoc ones apart, exploratory claims only counted; '—' for no claims."""
    primary = [c for c in comparisons if c.get("family", "primary") == "primary" and ran(c)]

    def counted(group: list[dict[str, Any]]) -> str:
        counts = {v: sum(c["verdict"] == v for c in group) for v in VERDICTS}
        return ", ".join(f"{n} {v}" for v, n in counts.items() if n)

    parts = [counted([c for c in primary if not c.get("post_hoc")])]
    late = counted([c for c in primary if c.get("post_hoc")])
    parts.append(f"post hoc: {late}" if late else "")
    not_run = sum(not ran(c) for c in comparisons)
    explored = sum(c.get("family") == "exploratory" and ran(c) for c in comparisons)
    parts += [
        f"{not_run} not run" if not_run else "",
        f"{explored} exploratory" if explored else "",
    ]
    return "; ".join(p for p in parts if p) or "—"


def decisive_cell(reports: dict[tuple[str, str], dict[str, Any]], question: Question) -> str:
    """The question's verdict in the decisive design that asks it (from its committed report
    at `thesis` scale): its verdict, 'exploratory', 'running: NAME, no look yet' before its
    first look's report, or 'no decisive design' where none asks it."""
    found_claim = question.decisive_claim()
    if found_claim is None:
        return "none (no decisive design asks it)"
    name, claim = found_claim
    declared = next(c for c in load_shipped(name).comparisons if c.name == claim)
    which = f"`{claim}`" if claim != question.claim else ""
    found = _claims(reports.get((name, "thesis"))).get(claim)
    if found is None or not ran(found):
        return f"running: {name}, no look yet ({declared.family}{', ' if which else ''}{which})"
    where = f"{name}: {which}, " if which else ""
    if declared.family == "exploratory":
        return f"exploratory ({where}{runs_text(found)})"
    return f"{verdict_words(found)} ({where}{runs_text(found)})"


class AnswerRow(NamedTuple):
    """One question's cells: asked, where, its verdict per scale, Δ at small, the other claims."""

    question: str
    claim: str  # "experiment: `claim`"
    small: str
    thesis: str
    decisive: str
    delta: str  # small: Δ [interval]
    others: str  # small: the tally of the other claims on it


def answer_rows(reports: dict[tuple[str, str], dict[str, Any]]) -> list[AnswerRow]:
    """A row per question: its verdict at `small`, at `thesis` scale and in its decisive
    experiment (the page's answers table and the dashboard's)."""
    rows = []
    for question in load_questions():
        small = _claims(reports.get((question.experiment, "small")))
        thesis = _claims(reports.get((question.experiment, "thesis")))
        others = [small[name] for name in question.also if name in small]
        rows.append(
            AnswerRow(
                question.text,
                f"{question.experiment}: `{question.claim}`",
                answer(small.get(question.claim)),
                answer(thesis.get(question.claim)) if thesis else "—",
                decisive_cell(reports, question),
                measured(small.get(question.claim)),
                tally(others),
            )
        )
    return rows


def answers_table(reports: dict[tuple[str, str], dict[str, Any]]) -> str:
    """The headline table: a row per question, its verdict at `small` and at `thesis` scale."""
    out = [
        "| question | experiment: answering claim | small | thesis | decisive (thesis scale) "
        "| small: Δ [interval] | small: the other claims on it |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in answer_rows(reports):
        out.append("| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |")
    return "\n".join(out) + "\n"
