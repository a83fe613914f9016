"""Generated scenes, the ground-truth renderer and the closed-loop simulation (DESIGN §10)."""
