"""Component catalogue and drive-chain rules (issue 12): parts of a feed axis and the physics that lumps them."""
