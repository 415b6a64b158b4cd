"""Suite-wide settings.

pytest runs with `-n 2` (two worker processes on a 2-core machine). torch's default of one
thread per core then oversubscribes the CPU, and small batched updates slowed down twentyfold in
that state (benchmarks/training.py measures it): every worker uses one torch thread.
"""

import torch

torch.set_num_threads(1)
