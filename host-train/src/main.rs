//! `hexapod`: the host-side command line (motion priors, training, evaluation).
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "hexapod", version, about = "Hexapod locomotion: motion priors, training, evaluation")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {}
}
