"""btfrig's studies: benches and the measurements behind the docs' tables and figures.

Each study measures the rig, the processing or the renderer against a known truth or a
baseline drawn in the same run, and returns rows. The studies sit above the orchestrator
(some run whole sessions through it) and below its command line, which lists them
(``rig bench``); nothing below imports them.
"""
