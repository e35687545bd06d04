"""The bottom layer: input checks and host-side rotation helpers (numpy only, no Warp)."""
