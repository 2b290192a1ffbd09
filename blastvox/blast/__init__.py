"""The blast-wave model shared by every stage: Kingery-Bulmash reference data,
the modified Friedlander profile and its exact impulse, TNT equivalence."""
