"""Training jobs: `coexist train ...` run as subprocesses, their state kept in the store's database.

| module     | what                                                                   |
|------------|------------------------------------------------------------------------|
| `spec`     | `JobSpec`: what to train, validated; the `coexist train` command line  |
| `table`    | `JobTable`: the `training_jobs` rows (submit, claim, cancel, recover)  |
| `runner`   | `JobRunner`: a thread that runs queued jobs one at a time, stops them  |

Used by the REST job API (`services.jobs_api`).
"""

from trainer.jobs.runner import JobRunner
from trainer.jobs.spec import JOB_KINDS, JobSpec, train_command
from trainer.jobs.table import Job, JobStatus, JobTable

__all__ = ["JOB_KINDS", "Job", "JobRunner", "JobSpec", "JobStatus", "JobTable", "train_command"]
