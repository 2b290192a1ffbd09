"""File plumbing shared by the stages: deterministic, atomic .npz contracts."""
