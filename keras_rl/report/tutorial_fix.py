"""The tutorial's community fix (post 003): each upstream proposal measured against the tutorial as
published, in Keras and in the tutorial's own PyTorch code, as ``results/cartpole/tutorial-fix/plan.md``
planned before its runs.

One home for what the findings table (``tables/findings.py``) and the forest (``tables/forest.py``)
say about these arms: each proposal's ``--variant`` (``posts/cartpole.py``), its folders under
``results/``, the commands that made them, the seeds each reading waits for and the published arm it
is read against.
"""

from __future__ import annotations

from dataclasses import dataclass

from keras_rl.report.certified import TORCH_ARMS

FRAMEWORKS = ("keras", "torch")
PLANNED_SEEDS = {"keras": 100, "torch": 30}
"""Seeds per arm before the first reading (plan.md: 100+ in Keras, 30+ in the tutorial's PyTorch code)."""
PUBLISHED: dict[str, tuple[str, ...]] = {
    "keras": ("engines/cartpole/compiled",),
    "torch": TORCH_ARMS[("cartpole", False)],
}
"""The tutorial as published, each framework's arm the proposals are read against (plan.md): the
PyTorch one is the certified comparison's arm, several run sets (``report.certified.arm``)."""
FRAMEWORK_NAMES = {"keras": "Keras", "torch": "the tutorial's PyTorch code"}
MAKES = {"keras": "--engine compiled", "torch": "--framework torch"}
"""How each framework's arm was run: Keras on the compiled engine, PyTorch as the tutorial wrote it."""


@dataclass(frozen=True)
class TutorialFix:
    variant: str
    """``--variant`` of ``keras-rl reproduce cartpole`` (``posts/cartpole.py``'s VARIANTS)."""
    upstream: str
    """The proposal, named as a fact about the world."""
    shown: str
    """What upstream backed it with, as the findings table's cell goes on after ``upstream``."""
    torch_second_look: int = 0
    """Seeds of a second reading of the PyTorch arm, planned before its runs (plan.md's addenda); 0: none."""

    def readings(self, fw: str) -> tuple[int, ...]:
        """Each planned reading's seeds: the arms are read on seeds 0 to n - 1, at each n, and at no other."""
        return (PLANNED_SEEDS[fw],) + ((self.torch_second_look,) if fw == "torch" and self.torch_second_look else ())

    @property
    def said(self) -> str:
        """The findings table's "the post's own number" cell."""
        return self.upstream + self.shown

    def folder(self, fw: str) -> str:
        """The arm's run-set folder under ``results/``."""
        return f"cartpole/tutorial-fix/{self.variant}" + ("-torch" if fw == "torch" else "")

    def command(self, fw: str, seeds: str) -> str:
        """The command that made the arm's folder, for ``seeds``."""
        return (
            f"keras-rl reproduce cartpole --variant {self.variant} {MAKES[fw]} --seeds {seeds} --workers 1 --resume "
            f"--no-progress --min-success-rate 0 --out results/{self.folder(fw)}"
        )

    def label(self, fw: str, seeds: int) -> str:
        """The forest's row label for the reading at ``seeds``."""
        looks = self.readings(fw)
        look = "" if len(looks) == 1 else (", first look" if seeds == looks[0] else ", second look")
        return f"cartpole, {self.upstream} ({FRAMEWORK_NAMES[fw]}){look}"


TUTORIAL_FIXES = (
    TutorialFix("issue-3080", "pytorch/tutorials #3080's values", " (one curve)"),
    TutorialFix("pr-3384", "pytorch/tutorials PR #3384's values", ", merged (two runs)", torch_second_look=100),
)
