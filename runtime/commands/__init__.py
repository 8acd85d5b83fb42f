"""The command-line commands: `goalvla` and the work behind each of its commands."""
