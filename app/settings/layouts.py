"""The two layouts a run config has been written in, and the move from the first to the second.

Layout 1 (every file before issue #46): GNP's sections at the top (`controller`, `evolution`),
a net's in `neuro` (`optimiser` naming the family) and a family registered from outside in
`family` (`name` naming it), none of them: GNP. Layout 2: one `brain` section, its `family`
naming the family and the rest the family's own settings (GNP's `controller` and `evolution`).

    layout 1                                layout 2
    controller = {…}, evolution = {…}       brain = {controller = {…}, evolution = {…}}
    neuro = {optimiser = "cmaes", …}        brain = {family = "cmaes", …}
    family = {name = "vehicle", …}          brain = {family = "vehicle", …}

`layout_2` moves keys only (it knows no family's settings), so it applies to a whole stored
config and to each layer of one (a preset, a file, an option, an experiment's arm) before the
layers merge. `layout_1` maps back, for a run's identity only (`app.experiments.ledger`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from app.settings.families import DEFAULT_BRAIN

GNP_SECTIONS = ("controller", "evolution")
"""GNP's sections, at the top in layout 1 and in `brain` in layout 2."""
NET_FAMILIES = ("cmaes", "neat")
"""The families layout 1 wrote in its `neuro` section (`optimiser`)."""
LAYOUT_1 = (*GNP_SECTIONS, "neuro", "family")
"""The keys that mark a config (or a layer of one) as written in layout 1."""


def deep_merge(base: dict[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """`base` with `overrides` over it, tables merged key by key (a config's layers)."""
    merged = dict(base)
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
            merged[key] = deep_merge(dict(merged[key]), value)
        else:
            merged[key] = value
    return merged


def layout_2(data: Mapping[str, Any]) -> dict[str, Any]:
    """`data` (a config or a layer of one, raw) in layout 2; already so: unchanged.

    A layout-1 `neuro` or `family` section names its family; GNP's sections beside it were
    unused by such a run and are dropped. `neuro = null, family = null` (how GNP was selected)
    names GNP; a `neuro` or `family` that is neither is kept, for the model to refuse. A
    `brain` section given too wins over what is moved into it.
    """
    if not any(key in data for key in LAYOUT_1):
        return dict(data)
    odd = {k for k in ("neuro", "family") if not isinstance(data.get(k), Mapping | None)}
    moved = {key: value for key, value in data.items() if key not in LAYOUT_1 or key in odd}
    brain: dict[str, Any] = {}
    other = [(data.get(k), n) for k, n in (("neuro", "optimiser"), ("family", "name"))]
    named = [(dict(section), key) for section, key in other if isinstance(section, Mapping)]
    if named:
        section, key = named[0]
        brain = {"family": section.pop(key, None), **section}
        if brain["family"] is None:
            del brain["family"]
    else:
        if any(k in data for k in ("neuro", "family")) and not odd:  # both null: GNP selected
            brain["family"] = DEFAULT_BRAIN
        brain |= {k: data[k] for k in GNP_SECTIONS if k in data}
    given = data.get("brain")
    if isinstance(given, Mapping):
        brain = deep_merge(brain, given)
    moved["brain"] = brain
    return moved


def layout_1(data: Mapping[str, Any], family: str) -> dict[str, Any]:
    """A layout-2 config's settings (`data`: as dumped, e.g. only those off their defaults) in
    layout 1, its brain being of `family`: a run's identity as every committed ledger holds it.
    (A net's or an outside family's run of layout 1 also held GNP's unused sections; its
    identity here has none.)"""
    brain = {k: v for k, v in (data.get("brain") or {}).items() if k != "family"}
    out: dict[str, Any] = {k: data[k] for k in ("seed",) if k in data}
    if family == DEFAULT_BRAIN:
        out |= {k: brain[k] for k in GNP_SECTIONS if k in brain}
    out |= {k: v for k, v in data.items() if k not in ("seed", "brain")}
    if family in NET_FAMILIES:
        out["neuro"] = {"optimiser": family, **brain}
    elif family != DEFAULT_BRAIN:
        out["family"] = {"name": family, **brain}
    return out
