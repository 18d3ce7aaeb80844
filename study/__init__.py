"""The study engine: protocols, counterbalanced schedules, sessions, the store, simulated users."""
