//! `hexapod eval`'s terrain test: robots walk forward at a fixed command for one episode on
//! each kind of tile (slopes, rough slopes, stairs up and down, blocks) at a few difficulty
//! rows, and the report gives, per tile and row, how many fell and how far they got.
//!
//! Robots start near the tile's centre with a random heading; the tiles are pyramids, so
//! every heading climbs (or descends) the feature, as in legged_gym.

use crate::algo::ppo::Ppo;
use crate::config::TrainConfig;
use host_sim::terrain::TerrainConfig;
use host_sim::vec_env::VecEnv;
use serde::Serialize;

/// Command of the terrain test (vx, vy, wz).
pub const TERRAIN_TEST_COMMAND: [f32; 3] = [0.3, 0.0, 0.0];
/// Length of each run, s: 3 m at the command, about what separates a robot starting within
/// 1.4 m of the tile's centre from the edge of its 8 m tile.
pub const TERRAIN_TEST_DURATION_S: f32 = 10.0;
/// Difficulties tested, as fractions of the hardest row.
pub const TERRAIN_TEST_DIFFICULTIES: [f32; 3] = [0.2, 0.6, 1.0];

/// One tile kind at one row.
#[derive(Debug, Serialize)]
pub struct TileResult {
    /// Tile kind.
    pub kind: String,
    /// Terrain row (difficulty level).
    pub level: usize,
    /// The feature's size at that row.
    pub feature: String,
    /// Robots tested.
    pub robots: usize,
    /// Fraction that fell (terminated) within the run.
    pub fall_rate: f64,
    /// Mean straight-line distance from the start when the run ended or the robot fell, m.
    pub mean_distance_m: f64,
}

/// The terrain test's results.
#[derive(Debug, Serialize)]
pub struct TerrainWalkResult {
    /// Command (vx, vy, wz).
    pub command: [f32; 3],
    /// Length of each run, s.
    pub duration_s: f32,
    /// Distance a robot tracking the command perfectly covers, m.
    pub commanded_distance_m: f32,
    /// Per tile kind and row.
    pub tiles: Vec<TileResult>,
    /// Fall rate over all tiles.
    pub fall_rate: f64,
}

/// Terrain rows tested: the [`TERRAIN_TEST_DIFFICULTIES`] of `rows`, without repeats.
pub fn test_levels(rows: usize) -> Vec<usize> {
    let mut levels: Vec<usize> = TERRAIN_TEST_DIFFICULTIES
        .iter()
        .map(|d| (d * (rows.max(1) - 1) as f32).round() as usize)
        .collect();
    levels.dedup();
    levels
}

/// Runs the terrain test with `per_kind` robots on each tile kind. A checkpoint trained on
/// flat ground is tested on the default tile grid.
pub fn terrain_walk(
    cfg: &TrainConfig,
    ppo: &mut Ppo,
    per_kind: usize,
) -> anyhow::Result<TerrainWalkResult> {
    let mut sim = cfg.resolved_sim();
    if !sim.terrain.tiles {
        sim.terrain = TerrainConfig {
            tiles: true,
            ..TerrainConfig::default()
        };
    }
    let kinds = sim.terrain.columns.clone();
    let n = kinds.len() * per_kind;
    sim.num_envs = n;
    sim.curriculum = false;
    sim.push.enabled = false;
    sim.episode_length_s = TERRAIN_TEST_DURATION_S + 1.0;
    let steps = (TERRAIN_TEST_DURATION_S / hexapod_core::timing::POLICY_DT_S).round() as usize;
    let mut env = host_sim::env::HexapodEnv::new(sim.clone())?;
    let mut tiles = Vec::new();
    for level in test_levels(sim.terrain.rows) {
        for i in 0..n {
            env.set_terrain_tile(i, level, i % kinds.len());
            env.set_command(i, TERRAIN_TEST_COMMAND);
        }
        let mut obs = env.reset();
        let mut fell = vec![false; n];
        let mut distance_m = vec![0.0f32; n];
        for _ in 0..steps {
            let act = ppo.act(&obs, true)?;
            let res = env.step(&act.actions);
            for i in 0..n {
                if fell[i] {
                    continue;
                }
                if res.dones[i] && !res.time_outs[i] {
                    fell[i] = true;
                } else if !res.dones[i] {
                    let p = env.robot_state(i).base_pos_world_m;
                    let o = env.spawn_position_m(i);
                    distance_m[i] = (p[0] - o[0]).hypot(p[1] - o[1]);
                }
            }
            obs = res.obs;
        }
        for (column, kind) in kinds.iter().enumerate() {
            let robots: Vec<usize> = (0..n).filter(|i| i % kinds.len() == column).collect();
            let count = robots.len().max(1) as f64;
            tiles.push(TileResult {
                kind: format!("{kind:?}"),
                level,
                feature: env.terrain().feature(*kind, level),
                robots: robots.len(),
                fall_rate: robots.iter().filter(|&&i| fell[i]).count() as f64 / count,
                mean_distance_m: robots.iter().map(|&i| distance_m[i] as f64).sum::<f64>() / count,
            });
        }
    }
    let fall_rate = tiles.iter().map(|t| t.fall_rate).sum::<f64>() / tiles.len().max(1) as f64;
    Ok(TerrainWalkResult {
        command: TERRAIN_TEST_COMMAND,
        duration_s: TERRAIN_TEST_DURATION_S,
        commanded_distance_m: TERRAIN_TEST_COMMAND[0].hypot(TERRAIN_TEST_COMMAND[1])
            * TERRAIN_TEST_DURATION_S,
        tiles,
        fall_rate,
    })
}

/// Prints the terrain test as a table.
pub fn print(t: &TerrainWalkResult) {
    println!(
        "terrain test: ({:.1},{:.1},{:.1}) for {:.0} s ({:.1} m commanded), random headings",
        t.command[0], t.command[1], t.command[2], t.duration_s, t.commanded_distance_m
    );
    println!(
        "{:>20} {:>6} {:>32} {:>10} {:>12}",
        "tile", "level", "feature", "fall rate", "distance m"
    );
    for r in &t.tiles {
        println!(
            "{:>20} {:>6} {:>32} {:>10.2} {:>12.2}",
            r.kind, r.level, r.feature, r.fall_rate, r.mean_distance_m
        );
    }
    println!("terrain test fall rate {:.2}", t.fall_rate);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_span_the_rows() {
        assert_eq!(test_levels(6), vec![1, 3, 5]);
        assert_eq!(test_levels(10), vec![2, 5, 9]);
        assert_eq!(test_levels(1), vec![0]);
    }
}
