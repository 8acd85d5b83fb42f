"""Stage 1, goal state reasoning: instruction -> validated goal image, target masks and goal depth."""
