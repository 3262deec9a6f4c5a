"""Layer 4: controllers (the interface, gait phases, commands, FBL, FBL+, the spinal network
with its interneurons and CPGs) and delays."""
