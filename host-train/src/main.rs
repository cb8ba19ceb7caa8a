//! `hexapod`: the host-side command line (motion priors, training, evaluation).
use clap::{Parser, Subcommand};
use host_train::cli;

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "hexapod",
    version,
    about = "Hexapod locomotion: motion priors, training, evaluation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train a policy (PPO + AMP) from a TOML preset.
    Train(cli::train::TrainArgs),
    /// Warm-start a policy by cloning the scripted tripod gait (a checkpoint to resume).
    Pretrain(cli::pretrain::PretrainArgs),
    /// RMA's adaptation phase: regress the memory encoder of a teacher (`[rma]` preset) onto
    /// its environment-factor latent, actor and estimator frozen; writes a deployable checkpoint.
    RmaAdapt(cli::rma_adapt::RmaAdaptArgs),
    /// Generate the motion-prior dataset by trajectory optimization, check or replay it.
    Priors(cli::priors::PriorsArgs),
    /// Run a checkpoint and write its trajectory, plots and a 3D replay.
    Play(cli::play::PlayArgs),
    /// Evaluate a checkpoint: tracking error, fall rate, tripod score.
    Eval(cli::eval::EvalArgs),
    /// Run a checkpoint in MuJoCo beside the simulator (nominal model): eval's table for both.
    Sim2sim(cli::sim2sim::Sim2SimArgs),
    /// Draw a run's or checkpoint's metrics.csv as the training plots.
    Plot(cli::plot::PlotArgs),
    /// Average the weights of several checkpoints of one run into a checkpoint (stochastic
    /// weight averaging).
    Average(cli::average::AverageArgs),
    /// Many trainings from one file (presets x variants x seeds), each evaluated by the
    /// suite, locally or as a Slurm job array, gathered into one report.
    Sweep(cli::sweep::SweepArgs),
}

fn main() -> std::process::ExitCode {
    host_train::alloc::keep_freed_memory();
    host_train::threads::single_threaded_elementwise();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Train(args) => cli::train::run(args),
        Command::Pretrain(args) => cli::pretrain::run(args),
        Command::RmaAdapt(args) => cli::rma_adapt::run(args),
        Command::Priors(args) => cli::priors::run(args),
        Command::Play(args) => cli::play::run(args),
        Command::Eval(args) => cli::eval::run(args),
        Command::Sim2sim(args) => cli::sim2sim::run(args),
        Command::Plot(args) => cli::plot::run(args),
        Command::Average(args) => cli::average::run(args),
        Command::Sweep(args) => cli::sweep::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, leaving out a cause whose text the message before
/// it already contains (many errors print their source themselves). No backtrace: these are
/// the user's errors (a path, a config value), not the program's.
fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !line.contains(&text) {
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&text);
        }
    }
    line
}
