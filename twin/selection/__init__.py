"""Skill profiles and which elements a skill's maps are made of (SPARQL)."""
