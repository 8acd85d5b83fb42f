"""The operator console: a local web page bridged to the robot's Zenoh key space."""
