"""Simulation and the multi-step cost: the model's free run over records or shooting windows
(one ``lax.scan``), the cost as a stacked residual vector, and the initial state that best
explains a short window of measurements. Pure functions of arrays; nothing public here."""
