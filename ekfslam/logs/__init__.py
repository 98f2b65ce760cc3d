"""The logs floor: data sources (our run format, rosbag, TUM, frames, MRCLAM).

Imports core (never `core.filter`) and the leaves."""
