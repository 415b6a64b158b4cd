"""`coexist eval --suite pairs --env NAME`: every method on goal pairs of any registered
environment (`evaluation.pairs.command`), through the public engine and `Domain` APIs only."""
