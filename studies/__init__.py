"""The project's own studies of the filter: what chose its defaults and what the README reports.

Not part of the package: ``ekfslam`` holds what the notebooks, the main commands and a user's own
code need; these studies use it (any of it, public or not) and nothing in ``ekfslam`` imports
them. Run them from a checkout's root: ``python -m studies --help`` lists the commands
(README.md beside this file says what each one measures and where its figures are).
"""
