"""``thermodrift automl``: the search across pipeline families (see ``docs`` architecture, "AutoML across families").

Modules: :mod:`.space` (the conditional space and the portfolio), :mod:`.folds` (inner forward chaining over
working conditions), :mod:`.evaluate` (scoring a candidate), :mod:`.search` (portfolio, TPE, successive halving,
budget), :mod:`.ensemble` (greedy ensemble), :mod:`.leaderboard` (the table), :mod:`.job` (search, refit, outer
evaluation).
"""
