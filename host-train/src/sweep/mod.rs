//! Sweeps: many trainings from one file (presets x variants x seeds), each evaluated by the
//! paper suite, run one after another on this machine or as a Slurm job array, then gathered
//! into one report per controller over seeds (`hexapod sweep run | status | report`).

pub mod curves;
pub mod report;
pub mod slurm;
pub mod spec;
pub mod task;
