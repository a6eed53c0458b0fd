"""Each learning method's traits, in one table: the engine, the oracle and the lab read them here.

GNP-RL (RL) learns sub node selection only (Q_SS). GNP-TSRL adds a second stage on top of it:
branch selection (BS, chapter 3: Q_BS chooses among U branch connections) or credit (CS,
chapter 5: Q_CS chooses between a node's function and a skip through its credit branch).
Code asks for a trait (`cfg.traits.credit`), never for a method's name.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal, get_args

#: The learning methods: GNP-RL (sub node selection), GNP-TSRL with branch selection or credit.
Method = Literal["RL", "BS", "CS"]
METHODS: tuple[Method, ...] = get_args(Method)

#: The compiled kernel's flags for the second stage (`MethodTraits.kernel_code`); none of them
#: runs the first stage alone, as the live ablation runs every method.
BRANCH_SELECTION, CREDIT = 1, 2
FIRST_STAGE_ONLY = 0
#: The kernel's flag (beside the method's) for `GnpConfig.tie_break` "first": ε-greedy breaks a
#: tie among the maxima to the lowest index, with no draw (`gnp.engine.method_code`).
TIE_FIRST = 4
#: The kernel's flag for `GnpConfig.skip_reward` "step": a credit skip that ends a world step
#: earns that step's reward, as any step's last visit does (else 0, Eq. 5.3).
SKIP_EARNS = 8
#: The kernel's flag for `GnpConfig.processing_output` "function": a processing node sets
#: output 0 to the centre of its function's bin, not output f to its parameter.
EMIT_FUNCTION = 16


@dataclass(frozen=True)
class MethodTraits:
    """What distinguishes one learning method from the others.

    Attributes:
        branch_selection: the second stage chooses the branch connection u on Q_BS; the
            connection axis has U = `n_branch` entries (else 1).
        credit: the second stage chooses normal or credit on Q_CS; a node has credit branches.
        default_n_sub: sub nodes per node the thesis uses (Tables 2.4, 3.1, 5.1).
        ablated: what the method does with its second stage off, in words (`gnp.step`'s
            `second_stage=False`).
    """

    branch_selection: bool
    credit: bool
    default_n_sub: int
    ablated: str

    @property
    def two_stage(self) -> bool:
        """Whether the method has a second stage (GNP-TSRL)."""
        return self.branch_selection or self.credit

    @property
    def kernel_code(self) -> int:
        """The method as the compiled kernel reads it: its second stage's flags."""
        return BRANCH_SELECTION * self.branch_selection + CREDIT * self.credit

    def n_conn_branches(self, n_branch: int) -> int:
        """Size of the branch-connection axis of `conn` and `q_bs` for `n_branch` U."""
        return n_branch if self.branch_selection else 1


TRAITS: MappingProxyType[Method, MethodTraits] = MappingProxyType(
    {
        "RL": MethodTraits(False, False, 4, "has none"),
        "BS": MethodTraits(True, False, 2, "takes its greedy branch connection, Q_BS frozen"),
        "CS": MethodTraits(False, True, 2, "never takes its credit branch, Q_CS frozen"),
    }
)
"""Every method's traits, keyed like `METHODS`."""
