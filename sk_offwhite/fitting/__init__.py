"""The pure core of ``fit``: from validated records and a model structure to fitted blocks.

`_problem` builds the minimisation (initial values, free masks, bounds, weights) and runs the
solver, restarting a fit that is no model; `_sparsity` runs the three stages of a fit with a
dictionary (physics alone, penalised, pruned and refitted) and the term evidence; `_verdict`
judges whether a solver's answer is a model; `_start` gives the continuation start of a
restart. Nothing public here."""
