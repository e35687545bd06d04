"""The bottom layer: input checks, host-side rotation helpers (numpy only), and how much Warp prints."""
