"""chatterlab: chatter stability from structural models (placeholder, filled below)."""
