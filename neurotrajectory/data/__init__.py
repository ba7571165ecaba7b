"""Datasets of labelled windows of human driving and the commands they imply."""
