"""tinyline: N agents in a corridor of `CELLS` cells, each heading for its own cell; an agent
cannot step into an occupied cell nor pass another, so an agent between a partner and its cell
must step aside (beyond it) for the partner to arrive. A coexistence problem in ~150 lines, for
coexist's plugin tests."""
