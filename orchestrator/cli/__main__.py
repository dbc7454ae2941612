"""`python -m orchestrator.cli …` is the `rig` command."""

from orchestrator.cli import main

main()
