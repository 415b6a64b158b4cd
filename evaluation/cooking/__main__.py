"""`python -m evaluation.cooking STORE_URL OUT_DIR [EPISODES [TEMPERATURE]]`."""

import sys

from evaluation.cooking.report import main

main(sys.argv[1:])
