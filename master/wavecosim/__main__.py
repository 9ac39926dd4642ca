"""`python -m wavecosim`: the command line."""
from .cli import main

main()
