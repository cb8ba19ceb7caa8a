//! Subcommands of the `hexapod` binary, one file each.
