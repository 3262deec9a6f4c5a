"""Layer 0: what every stage uses (parameter tables, resources, small linear algebra)."""
