"""Minimal plans: the query and its answer, the two engines (symbolic search on BDDs, SAT
bounded model checking), the reductions the symbolic engine may use, the partial order of a
plan, and the transition and operation planners the runner asks."""
