"""The `rig` command line."""


def main() -> None:
    raise SystemExit("rig: CLI not assembled yet")
