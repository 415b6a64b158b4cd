"""Training backends beside the default in-process loops of `trainer.zoo`.

| module        | what                                                                   |
|---------------|------------------------------------------------------------------------|
| `jobs`        | batches of goals as portable jobs; `train_batch` trains and registers one |
| `once`        | idempotent registration: job marker in the lineage + a publish lock     |
| `ray_cluster` | `run_on_ray`: jobs as Ray tasks, stage after stage, retried on failure  |

The local backend (`trainer.zoo.run_tasks` / `run_impacts` / `run_joint`) stays the default and
imports none of this; Ray is imported only inside `run_on_ray`.
"""
