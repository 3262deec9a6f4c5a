"""Layer 2: Geyer muscle-tendon units and their metabolic energy."""
