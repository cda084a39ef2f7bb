"""Figures from result objects (matplotlib, no pyplot). Imported only lazily, by the results' `.plot()`
methods and by the front ends."""
