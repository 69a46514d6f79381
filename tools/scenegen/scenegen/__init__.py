"""scenegen - synthetic table scenes with exact ground truth for the rbx1 perception pipeline."""
