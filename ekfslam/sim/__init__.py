"""The simulation floor: the seed's robot and camera simulated, and the test scenarios.

Imports core (never `core.filter`), logs and the leaves."""
