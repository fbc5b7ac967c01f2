"""Controllers that act in an env: PX4-style cascade (+ observer feedforward), SB3 policy adapter."""
