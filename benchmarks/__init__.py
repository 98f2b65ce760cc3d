"""The project's benchmarks: how fast the filter, the commands and the live panel are.

Not part of the package (as scikit-learn keeps its ``benchmarks/``): they use ``ekfslam``, its
internals included, and nothing in ``ekfslam`` imports them. Run them from a checkout's root:
``python -m benchmarks --help`` lists the commands (README.md beside this file says what each
one measures and where its figures are). Speed is measured here, never asserted in a test.
"""
