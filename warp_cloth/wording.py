"""How the program's messages say a count."""


def counted(n: int, one: str, many: str | None = None) -> str:
    """``counted(1, "substep")`` -> ``1 substep``, ``counted(3, "batch", "batches")`` -> ``3 batches``."""
    return f"{n} {one if n == 1 else (many or one + 's')}"
