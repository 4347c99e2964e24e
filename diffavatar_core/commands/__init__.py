"""One module per `diffavatar` sub-command. Each defines `register(subparsers)` which adds its
parser and sets `func` (args -> exit code). cli.py discovers them, so adding a command never
touches another command's file."""
