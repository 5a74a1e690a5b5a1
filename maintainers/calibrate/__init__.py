"""The check's calibration (``python -m maintainers calibrate``): the error rates of each candidate rule on the
committed baseline and mutant runs, the family-wise rate of the three-post command, the power
against held-out mutants, the sequential designs and the bisect's levels. ``rules`` and
``designs`` write the package data ``check`` reads (``calibration.json``, ``sequential.json``)."""
