"""Export stage: SimCache -> USD (.usda/.usdc/.usd) and glTF 2.0 (.gltf/.glb) caches."""
