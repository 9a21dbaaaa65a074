"""Writers of formats other tools read (DIMAP v1 scenes)."""
