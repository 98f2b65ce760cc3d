"""The ui floor: the live tuner and the ipywidgets panel. Imports analysis, viz and below."""
