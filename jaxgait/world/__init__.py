"""Layer 3: terrains, environments (pushes), ground contact and viewing scenes."""
