"""Many renders: ``render_many`` with a local worker pool, Ray or any ``concurrent.futures`` executor."""
