"""The trainer: soft-Q task networks (eqs. 3-5), self-play impact networks (eqs. 6-7) and the
joint-learner baseline, many networks stacked into one update (`loop.py`, `soft_q.py`), quality
gates (`gates.py`), registration with lineage (`publish.py`), the zoo pipeline (`zoo.py`), the
Ray backend (`backends/`) and the job API runner (`jobs/`)."""
