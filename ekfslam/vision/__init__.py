"""The vision floor: AprilTags in camera frames -> range and bearing, and the arena renderer.

Imports core (never `core.filter`) and the leaves; cv2 is its dependency."""
