"""Layer 4: controllers (the interface, gait phases, commands, FBL, FBL+) and delays."""
