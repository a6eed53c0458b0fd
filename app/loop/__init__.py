"""The one loop every phase steps robots through (`rollout`), its compiled form, what it records
and the seeded random streams its lives draw from."""
