//! `hexapod eval --suite paper`: the paper's experiments as one reproducible report, for one
//! or several checkpoints side by side. Protocols: `push` (velocity-disturbance tolerance,
//! Table III), `terrain` (stairs and slopes, Fig. 5), `step` (the outdoor 15 cm step),
//! `beyond` (25 cm stairs, 35 deg slopes), `friction` (the 30 deg ramp and 20 cm stairs at
//! fixed contact friction), `sine` (sinusoidal commands, Fig. 3), `curriculum` (terrain row over
//! training, Fig. 4).
//!
//! Beside checkpoints, the model-based MPC ([`crate::mpc`], `--mpc [params.toml]`) runs as a
//! controller of its own (under the default config's randomization; `curriculum` does not
//! apply to it: it is not trained).
//!
//! Every checkpoint is loaded and checked before anything runs; the report (JSON, Markdown,
//! PNG plots) is written to a temporary directory and moved into place only when every
//! protocol finished for every checkpoint, so a failed run leaves no partial report.

pub mod batch;
pub mod controller;
pub mod curriculum;
pub mod friction;
pub mod plots;
pub mod push;
pub mod report;
pub mod sine;
pub mod terrain;

use crate::checkpoint::{load_for_inference, load_iteration};
use crate::config::{EnvKind, TrainConfig};
use crate::mpc::{MpcController, MpcParams};
use anyhow::{bail, Context};
use batch::Conditions;
use controller::SuiteController;
use report::{ControllerReport, SuiteReport};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Suites known.
pub const SUITES: [&str; 1] = ["paper"];
/// Protocols of the paper suite, in the order they run.
/// `beyond` walks the terrain test's 25 cm stairs and 35 deg slopes, past the paper's range;
/// `friction` walks its 30 deg ramp and 20 cm stairs at fixed contact friction coefficients.
pub const PROTOCOLS: [&str; 7] = [
    "push",
    "terrain",
    "step",
    "beyond",
    "friction",
    "sine",
    "curriculum",
];
/// Trials per test point (the paper: 10).
pub const TRIALS: usize = 10;
/// Trials per test point in the quick variant.
pub const QUICK_TRIALS: usize = 2;
/// Bisection of the push protocol: rounds and magnitudes per bracket per round.
pub const PUSH_SEARCH: (usize, usize) = (3, 3);
/// The quick variant's push search.
pub const QUICK_PUSH_SEARCH: (usize, usize) = (1, 1);
/// Longest terrain trial the suite runs, s.
pub const MAX_TERRAIN_DURATION_S: f32 = 60.0;

/// Highest contact friction `--contact-friction` takes.
pub const MAX_CONTACT_FRICTION: f32 = 5.0;

/// What `hexapod eval --suite` was asked for.
#[derive(Clone, Debug)]
pub struct SuiteOptions {
    /// Suite name.
    pub suite: String,
    /// Checkpoint directories, one controller each.
    pub checkpoints: Vec<PathBuf>,
    /// Also run the MPC: `Some(None)` with its default parameters, `Some(Some(file))` with
    /// parameters from a TOML file.
    pub mpc: Option<Option<PathBuf>>,
    /// Output directory.
    pub out: PathBuf,
    /// Protocols to run (empty: all).
    pub protocols: Vec<String>,
    /// The reduced variant.
    pub quick: bool,
    /// Trials per test point (default 10, quick 2).
    pub trials: Option<usize>,
    /// Seed.
    pub seed: u64,
    /// Length of each terrain trial, s (default [`terrain::DURATION_S`]).
    pub terrain_duration_s: Option<f32>,
    /// Friction range of the feet's contacts with the ground, `[lo, hi]` (default
    /// [`batch::SUITE_FRICTION`]).
    pub contact_friction: Option<Vec<f32>>,
    /// Cell of the course's height grid, m (default `host_sim::course::CELL_M`): finer
    /// draws steeper risers.
    pub course_cell_m: Option<f32>,
}

/// Checks the options; returns the protocols to run, in run order.
pub fn validate(o: &SuiteOptions) -> anyhow::Result<Vec<&'static str>> {
    if !SUITES.contains(&o.suite.as_str()) {
        bail!("unknown suite `{}` (known: {})", o.suite, SUITES.join(", "));
    }
    for p in &o.protocols {
        if !PROTOCOLS.contains(&p.as_str()) {
            bail!(
                "unknown protocol `{p}` (the {} suite has: {})",
                o.suite,
                PROTOCOLS.join(", ")
            );
        }
    }
    if o.trials == Some(0) {
        bail!("--trials must be at least 1");
    }
    if let Some(d) = o.terrain_duration_s {
        if !(d > 0.0 && d <= MAX_TERRAIN_DURATION_S) {
            bail!("--terrain-duration-s must be in (0, {MAX_TERRAIN_DURATION_S}] s, got {d}");
        }
    }
    if let Some(mu) = &o.contact_friction {
        if !matches!(mu.as_slice(), [lo, hi] if *lo > 0.0 && lo <= hi && *hi <= MAX_CONTACT_FRICTION)
        {
            bail!(
                "--contact-friction must be LO,HI with 0 < LO <= HI <= {MAX_CONTACT_FRICTION}, got {mu:?}"
            );
        }
    }
    if let Some(cell_m) = o.course_cell_m {
        host_sim::course::check_cell(cell_m)
            .map_err(|e| anyhow::anyhow!("--course-cell-m: {e}"))?;
    }
    if o.checkpoints.is_empty() && o.mpc.is_none() {
        bail!("give at least one --checkpoint or --mpc");
    }
    Ok(PROTOCOLS
        .iter()
        .copied()
        .filter(|p| o.protocols.is_empty() || o.protocols.iter().any(|q| q == p))
        .collect())
}

/// A short name for a checkpoint in the tables: its directory, with the run's for
/// `<run>/checkpoints/model_N` and the report's for a checkpoint committed beside its report,
/// `<report>/checkpoint-model_N` ([`crate::checkpoint::name_parts`]).
pub fn controller_name(checkpoint: &Path) -> String {
    crate::checkpoint::display_name_with(checkpoint, "/")
}

fn trained_on(cfg: &TrainConfig) -> String {
    let t = cfg.resolved_sim().terrain;
    if t.tiles {
        format!(
            "tile grid, {} rows (hardest: {:.0} deg, {:.2} m stairs)",
            t.rows, t.max_slope_deg, t.max_step_height_m
        )
    } else {
        "flat ground".into()
    }
}

/// Name of the MPC in reports.
pub const MPC_NAME: &str = "mpc";

struct Controller {
    name: String,
    /// The checkpoint directory (`None`: the MPC).
    checkpoint: Option<PathBuf>,
    /// What the report shows as the checkpoint.
    source: String,
    cfg: TrainConfig,
    policy: Box<dyn SuiteController>,
}

/// Runs the suite and writes the report into `o.out`.
pub fn run(o: &SuiteOptions) -> anyhow::Result<()> {
    let protocols = validate(o)?;
    let trials = o
        .trials
        .unwrap_or(if o.quick { QUICK_TRIALS } else { TRIALS });
    let mut controllers = Vec::new();
    for dir in &o.checkpoints {
        if !dir.is_dir() {
            bail!("checkpoint {}: no such directory", dir.display());
        }
        let (cfg, ppo) =
            load_for_inference(dir).with_context(|| format!("checkpoint {}", dir.display()))?;
        if cfg.env.kind != EnvKind::Sim {
            bail!(
                "checkpoint {}: trained on the `{:?}` stand-in; the suite needs a simulator policy",
                dir.display(),
                cfg.env.kind
            );
        }
        let mut name = controller_name(dir);
        let same = controllers
            .iter()
            .filter(|c: &&Controller| c.name == name || c.name.starts_with(&format!("{name} #")))
            .count();
        if same > 0 {
            name = format!("{name} #{}", same + 1);
        }
        controllers.push(Controller {
            name,
            checkpoint: Some(dir.clone()),
            source: dir.display().to_string(),
            cfg,
            policy: Box::new(ppo),
        });
    }
    if let Some(file) = &o.mpc {
        let params = match file {
            Some(f) => MpcParams::load(f)?,
            None => MpcParams::default(),
        };
        controllers.push(Controller {
            name: MPC_NAME.into(),
            checkpoint: None,
            source: match file {
                Some(f) => format!("MPC, parameters {}", f.display()),
                None => "MPC, default parameters".into(),
            },
            cfg: TrainConfig::default(),
            policy: Box::new(MpcController::new(params)?),
        });
    }
    let (rounds, k) = if o.quick {
        QUICK_PUSH_SEARCH
    } else {
        PUSH_SEARCH
    };
    let mut reports = Vec::new();
    for c in &mut controllers {
        let mut conditions = Conditions::new(&c.cfg, o.seed, trials, o.quick)?;
        if let Some([lo, hi]) = o.contact_friction.as_deref() {
            conditions.set_contact_friction([*lo, *hi])?;
        }
        if let Some(d) = o.terrain_duration_s {
            conditions.terrain_duration_s = d;
        }
        if let Some(cell_m) = o.course_cell_m {
            conditions.course_cell_m = cell_m;
        }
        let mut r = ControllerReport {
            name: c.name.clone(),
            checkpoint: c.source.clone(),
            iteration: c.checkpoint.as_ref().and_then(|d| load_iteration(d).ok()),
            trained_on: match c.checkpoint {
                Some(_) => trained_on(&c.cfg),
                None => "model-based, not trained".into(),
            },
            conditions: conditions.clone(),
            push: None,
            terrain: None,
            beyond_paper: None,
            friction_sweep: None,
            sine: None,
            curriculum: None,
            wall_clock_s: BTreeMap::new(),
        };
        let time = |r: &mut ControllerReport, name: &str, t: Instant| {
            let s = t.elapsed().as_secs_f64();
            eprintln!("{}: {name} done in {s:.0} s", r.name);
            r.wall_clock_s.insert(name.to_string(), s);
        };
        if protocols.contains(&"push") {
            let t = Instant::now();
            r.push = Some(push::run(
                &c.cfg,
                c.policy.as_mut(),
                &conditions,
                rounds,
                k,
            )?);
            time(&mut r, "push", t);
        }
        let (with_terrain, with_step) =
            (protocols.contains(&"terrain"), protocols.contains(&"step"));
        if with_terrain || with_step {
            let t = Instant::now();
            r.terrain = Some(terrain::run(
                &c.cfg,
                c.policy.as_mut(),
                &conditions,
                with_terrain,
                with_step,
            )?);
            let label = match (with_terrain, with_step) {
                (true, true) => "terrain + step",
                (true, false) => "terrain",
                _ => "step",
            };
            time(&mut r, label, t);
        }
        if protocols.contains(&"beyond") {
            let t = Instant::now();
            r.beyond_paper = Some(terrain::run_beyond(&c.cfg, c.policy.as_mut(), &conditions)?);
            time(&mut r, "beyond", t);
        }
        if protocols.contains(&"friction") {
            let t = Instant::now();
            r.friction_sweep = Some(friction::run(&c.cfg, c.policy.as_mut(), &conditions)?);
            time(&mut r, "friction", t);
        }
        if protocols.contains(&"sine") {
            let t = Instant::now();
            r.sine = Some(sine::run(&c.cfg, c.policy.as_mut(), &conditions)?);
            time(&mut r, "sine", t);
        }
        if protocols.contains(&"curriculum") {
            match &c.checkpoint {
                Some(checkpoint) => {
                    let rows = if c.cfg.resolved_sim().terrain.tiles {
                        c.cfg.resolved_sim().terrain.rows
                    } else {
                        0
                    };
                    r.curriculum = Some(curriculum::run(checkpoint, rows)?);
                }
                None => eprintln!("{}: curriculum skipped (not a trained policy)", r.name),
            }
        }
        reports.push(r);
    }
    write(o, &protocols, reports)
}

fn command_line() -> String {
    let mut args: Vec<String> = std::env::args().collect();
    if let Some(first) = args.first_mut() {
        *first = "hexapod".into();
    }
    args.join(" ")
}

/// Writes the report into a temporary directory beside `o.out`, then moves its files in.
fn write(
    o: &SuiteOptions,
    protocols: &[&str],
    controllers: Vec<ControllerReport>,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(&o.out).with_context(|| format!("creating {}", o.out.display()))?;
    let tmp = o.out.join(format!(".suite-partial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(tmp.join("plots"))
        .with_context(|| format!("creating {}", tmp.display()))?;
    let result = (|| -> anyhow::Result<SuiteReport> {
        let plots = plots::draw_all(&tmp.join("plots"), &controllers)
            .map_err(anyhow::Error::msg)
            .context("drawing the plots")?;
        let report = SuiteReport {
            suite: o.suite.clone(),
            command: command_line(),
            protocols: protocols.iter().map(|p| p.to_string()).collect(),
            complete: true,
            plots: plots
                .iter()
                .filter_map(|p| p.file_name())
                .map(|f| format!("plots/{}", f.to_string_lossy()))
                .collect(),
            controllers,
        };
        std::fs::write(
            tmp.join("report.json"),
            serde_json::to_string_pretty(&report)?,
        )?;
        std::fs::write(tmp.join("report.md"), report.markdown())?;
        Ok(report)
    })();
    let report = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(e);
        }
    };
    std::fs::create_dir_all(o.out.join("plots"))?;
    for p in &report.plots {
        std::fs::rename(tmp.join(p), o.out.join(p))
            .with_context(|| format!("moving {p} into {}", o.out.display()))?;
    }
    for f in ["report.json", "report.md"] {
        std::fs::rename(tmp.join(f), o.out.join(f))
            .with_context(|| format!("moving {f} into {}", o.out.display()))?;
    }
    let _ = std::fs::remove_dir_all(&tmp);
    println!("{}", report.markdown());
    eprintln!("report: {}", o.out.join("report.md").display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts() -> SuiteOptions {
        SuiteOptions {
            suite: "paper".into(),
            checkpoints: vec![PathBuf::from("assets/policies/flat-tripod")],
            mpc: None,
            out: std::env::temp_dir().join("hexapod-suite-test"),
            protocols: Vec::new(),
            quick: true,
            trials: None,
            seed: 1,
            terrain_duration_s: None,
            contact_friction: None,
            course_cell_m: None,
        }
    }

    #[test]
    fn bad_input_is_named() {
        let mut o = opts();
        o.suite = "papr".into();
        assert!(validate(&o)
            .unwrap_err()
            .to_string()
            .contains("unknown suite `papr`"));
        let mut o = opts();
        o.protocols = vec!["push".into(), "stairs".into()];
        let e = validate(&o).unwrap_err().to_string();
        assert!(
            e.contains("unknown protocol `stairs`") && e.contains("terrain"),
            "{e}"
        );
        let mut o = opts();
        o.trials = Some(0);
        assert!(validate(&o).unwrap_err().to_string().contains("--trials"));
        for bad in [0.0, -1.0, 61.0, f32::NAN] {
            let mut o = opts();
            o.terrain_duration_s = Some(bad);
            let e = validate(&o).unwrap_err().to_string();
            assert!(e.contains("--terrain-duration-s"), "{e}");
        }
        for bad in [
            vec![0.6],
            vec![1.2, 0.6],
            vec![0.0, 1.0],
            vec![0.6, 9.0],
            vec![0.6, 0.8, 1.0],
        ] {
            let mut o = opts();
            o.contact_friction = Some(bad);
            let e = validate(&o).unwrap_err().to_string();
            assert!(e.contains("--contact-friction"), "{e}");
        }
        let mut o = opts();
        o.contact_friction = Some(vec![0.55, 1.75]);
        assert!(validate(&o).is_ok());
        for bad in [0.04, 0.2, 0.0, f32::NAN] {
            let mut o = opts();
            o.course_cell_m = Some(bad);
            let e = validate(&o).unwrap_err().to_string();
            assert!(e.contains("--course-cell-m"), "{e}");
        }
        let mut o = opts();
        o.course_cell_m = Some(0.025);
        assert!(validate(&o).is_ok());
        let mut o = opts();
        o.protocols = vec!["sine".into(), "push".into()];
        assert_eq!(validate(&o).unwrap(), vec!["push", "sine"]);
    }

    #[test]
    fn a_missing_or_mismatched_checkpoint_fails_before_any_report() {
        let out = std::env::temp_dir().join(format!("hexapod-suite-bad-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        let mut o = opts();
        o.out = out.clone();
        o.checkpoints = vec![
            PathBuf::from("../assets/policies/flat-tripod"),
            PathBuf::from("no/such/checkpoint"),
        ];
        let e = format!("{:#}", run(&o).unwrap_err());
        assert!(
            e.contains("no/such/checkpoint") && e.contains("no such directory"),
            "{e}"
        );
        assert!(!out.exists(), "nothing is written for a bad checkpoint");
        // The flat policy's weights under a config with another actor.
        let ckpt = out.with_extension("ckpt");
        std::fs::create_dir_all(&ckpt).unwrap();
        std::fs::copy(
            "../assets/policies/flat-tripod/policy.safetensors",
            ckpt.join("policy.safetensors"),
        )
        .unwrap();
        let config = std::fs::read_to_string("../assets/policies/flat-tripod/config.toml").unwrap();
        let changed = config.replace("actor_hidden = [\n    256,", "actor_hidden = [\n    200,");
        assert_ne!(config, changed);
        std::fs::write(ckpt.join("config.toml"), changed).unwrap();
        o.checkpoints = vec![ckpt.clone()];
        let e = format!("{:#}", run(&o).unwrap_err());
        assert!(e.contains("actor.layers.0") && e.contains("200"), "{e}");
        assert!(!out.exists());
        std::fs::remove_dir_all(&ckpt).unwrap();
    }

    #[test]
    fn the_mpc_is_a_controller_and_its_bad_parameters_fail_before_any_report() {
        let mut o = opts();
        o.checkpoints.clear();
        assert!(validate(&o)
            .unwrap_err()
            .to_string()
            .contains("give at least one --checkpoint or --mpc"));
        o.mpc = Some(None);
        assert!(validate(&o).is_ok());
        let out = std::env::temp_dir().join(format!("hexapod-suite-mpc-{}", std::process::id()));
        let params = out.with_extension("toml");
        std::fs::write(&params, "gait_period_s = 0.01\n").unwrap();
        o.out = out.clone();
        o.mpc = Some(Some(params.clone()));
        let e = format!("{:#}", run(&o).unwrap_err());
        assert!(
            e.contains("hexapod-suite-mpc")
                && e.contains("gait_period_s must be in [0.2, 3], got 0.01")
                && !e.contains('\n'),
            "{e}"
        );
        assert!(!out.exists());
        std::fs::remove_file(&params).unwrap();
    }

    #[test]
    fn names_come_from_the_directory() {
        assert_eq!(
            controller_name(Path::new("assets/policies/rough-climb")),
            "rough-climb"
        );
        assert_eq!(
            controller_name(Path::new("target/ci-pretrain-ppo/checkpoints/model_000001")),
            "ci-pretrain-ppo/model_000001"
        );
        assert_eq!(
            controller_name(Path::new(
                "assets/reports/amp-ablation-flat/gl-s1/checkpoint-model_006000"
            )),
            "gl-s1/model_006000"
        );
        assert_eq!(
            controller_name(Path::new("checkpoint-model_000100")),
            "checkpoint-model_000100"
        );
    }
}
