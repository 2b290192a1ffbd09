"""Export stage: SimCache -> USD (.usda/.usdc/.usd, .usdz) and glTF 2.0 (.gltf/.glb) caches."""
