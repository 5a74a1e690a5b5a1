"""``keras-rl check``: regression tests of the reproductions, with measured error rates.

``rules.py`` holds the pre-registered decision rule of each post and tier and the planted
regressions (mutants) they are measured against; ``statistics.py`` turns a run's episodes
into the per-seed statistics, decides "consistent" or "changed", and estimates a rule's
false-alarm rate and power by resampling; ``command.py`` runs the fresh seeds and writes
``check.md``, ``check.json`` and the plots.
"""
