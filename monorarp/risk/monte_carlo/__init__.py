"""Monte Carlo collision risk from IDM/MOBIL rollouts (paper section VI-B).

``idm`` (driver-model maths), ``drivers`` (sampled parameters), ``scene``
(estimated states -> road scene), ``rollout`` (batched simulation, numpy),
``rollout_numba`` (the same simulation compiled with numba), ``config``
(the estimator's settings), ``estimator`` (the registered ``("risk", "monte_carlo")`` component).
"""
