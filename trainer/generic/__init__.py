"""The trainer's generic machinery: the paper's task and impact learners on any registered
environment's own PettingZoo env, gated by generic quality gates, with the environment's numbers.

An environment that registers no trainer of its own (`envs.registry.EnvPlugin.training`) is
trained here. Its registration gives the numbers as a `GenericTraining`:

    from trainer.generic import GenericImpactConfig, GenericTaskConfig, GenericTraining

    TRAINING = GenericTraining(
        task=GenericTaskConfig(total_steps=3_000, gamma=0.9, success_threshold=0.8),
        impact=GenericImpactConfig(total_steps=2_000),
    )

| module     | what                                                                    |
|------------|-------------------------------------------------------------------------|
| `config`   | `GenericTaskConfig`, `GenericImpactConfig`, `GenericTraining`: the numbers |
| `worlds`   | `PairWorlds`: B PettingZoo envs of two agents stepped side by side       |
| `rollouts` | what the task and the impact learner see and earn (Algorithm 1's `Rollout`) |
| `gates`    | the generic quality gates                                               |
| `learners` | `GenericTrainer`, the `trainer.domain.EnvTrainer` of the above           |

No joint-learner baseline: an environment that wants one brings its own `EnvTrainer`.
"""

from trainer.generic.config import GenericImpactConfig, GenericTaskConfig, GenericTraining
from trainer.generic.learners import GenericTrainer

__all__ = ["GenericImpactConfig", "GenericTaskConfig", "GenericTrainer", "GenericTraining"]
