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

from maintainers.certified import TORCH_ARMS

FRAMEWORKS = ("keras", "torch", "vectorised")
"""The arms of each proposal: Keras, the tutorial's own PyTorch code, and PyTorch on the vectorised
engine (issue 53 item 5, plan.md's last addendum), once that engine was certified against the
tutorial's code (``results/cartpole/vectorised-torch``)."""
FRAMEWORK_OF = {"keras": "keras", "torch": "torch", "vectorised": "torch"}
"""Each arm's ``--framework``: the vectorised engine runs the tutorial's PyTorch DQN."""
PLANNED_SEEDS = {"keras": 100, "torch": 30, "vectorised": 100}
"""Seeds per arm before the first reading (plan.md: 100+ in Keras, 30+ in the tutorial's PyTorch
code, 100 on the vectorised engine)."""
PUBLISHED: dict[str, tuple[str, ...]] = {
    "keras": ("engines/cartpole/compiled",),
    "torch": TORCH_ARMS[("cartpole", False)],
    "vectorised": ("cartpole/vectorised-torch/seeds-0-199",),
}
"""The tutorial as published, each arm's reference the proposals are read against (plan.md): the
PyTorch one is the certified comparison's arm, several run sets (``maintainers.certified.arm``); the
vectorised engine's is its certification arm, read on the proposals' seeds."""
FRAMEWORK_NAMES = {
    "keras": "Keras",
    "torch": "the tutorial's PyTorch code",
    "vectorised": "PyTorch, the vectorised engine",
}
COMMANDS = {
    "keras": "keras-rl reproduce cartpole --variant {variant} --engine compiled --seeds {seeds} --workers 1 --resume "
    "--no-progress --min-success-rate 0 --out results/{folder}",
    "torch": "keras-rl reproduce cartpole --variant {variant} --framework torch --seeds {seeds} --workers 1 --resume "
    "--no-progress --min-success-rate 0 --out results/{folder}",
    "vectorised": "keras-rl reproduce cartpole --variant {variant} --framework torch --engine vectorised-compiled "
    "--seed-batch 8 --seeds {seeds} --workers 2 --no-progress --min-success-rate 0 --resume --out results/{folder}",
}
"""How each arm was run: Keras on the compiled engine, PyTorch as the tutorial wrote it, and PyTorch
in batches of 8 seeds on the vectorised engine (its queue, ``maintainers/queues/tutorial-fix-vectorised.tsv``)."""
FOLDER_SUFFIX = {"keras": "", "torch": "-torch", "vectorised": "-vectorised"}


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
        return f"cartpole/tutorial-fix/{self.variant}{FOLDER_SUFFIX[fw]}"

    def command(self, fw: str, seeds: str) -> str:
        """The command that made the arm's folder, for ``seeds``."""
        return COMMANDS[fw].format(variant=self.variant, seeds=seeds, folder=self.folder(fw))

    def label(self, fw: str, seeds: int) -> str:
        """The forest's row label for the reading at ``seeds``."""
        looks = self.readings(fw)
        look = "" if len(looks) == 1 else (", first look" if seeds == looks[0] else ", second look")
        return f"cartpole, {self.upstream} ({FRAMEWORK_NAMES[fw]}){look}"


TUTORIAL_FIXES = (
    TutorialFix("issue-3080", "pytorch/tutorials #3080's values", " (one curve)"),
    TutorialFix("pr-3384", "pytorch/tutorials PR #3384's values", ", merged (two runs)", torch_second_look=100),
)
