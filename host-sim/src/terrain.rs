//! Terrain: legged_gym-style tiles in a grid of difficulty rows x type columns, stored as
//! one height grid that becomes a rapier heightfield, plus height lookups for scans.
//!
//! World frame: z up. Tile (row, col) covers x in [row * tile, (row + 1) * tile) and
//! y in [col * tile, (col + 1) * tile), offset by a flat border on every side.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

/// The kinds of tiles, one per column (repeating when there are more columns).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TileKind {
    /// Flat ground.
    Flat,
    /// A pyramid slope, centre high.
    SmoothSlope,
    /// A pyramid slope, centre low, without noise: every heading from the centre climbs it.
    SmoothSlopeUp,
    /// A pyramid slope, centre low, with uniform height noise.
    RoughSlope,
    /// Pyramid stairs climbing from the centre outward.
    StairsUp,
    /// Pyramid stairs descending from the centre outward.
    StairsDown,
    /// Random rectangular blocks.
    DiscreteObstacles,
}

/// Friction coefficient of the ground, everywhere.
pub const GROUND_FRICTION: f32 = 1.0;

/// Terrain settings.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TerrainConfig {
    /// `false`: one flat plane (fast); `true`: the tile grid.
    pub tiles: bool,
    /// Difficulty levels (rows).
    pub rows: usize,
    /// Tile types, one per column.
    pub columns: Vec<TileKind>,
    /// Tile side length, m.
    pub tile_size_m: f32,
    /// Height grid spacing, m.
    pub cell_size_m: f32,
    /// Flat border around the grid, m.
    pub border_m: f32,
    /// Slope of the hardest row, degrees.
    pub max_slope_deg: f32,
    /// Stair step height of the hardest row, m.
    pub max_step_height_m: f32,
    /// Stair tread depth, m.
    pub step_depth_m: f32,
    /// Obstacle height of the hardest row, m.
    pub max_obstacle_height_m: f32,
    /// Height noise amplitude on rough slopes, m.
    pub rough_noise_m: f32,
    /// Seed of the random features.
    pub seed: u64,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        Self {
            tiles: false,
            rows: 10,
            columns: vec![
                TileKind::Flat,
                TileKind::SmoothSlope,
                TileKind::RoughSlope,
                TileKind::StairsUp,
                TileKind::StairsDown,
                TileKind::DiscreteObstacles,
            ],
            tile_size_m: 8.0,
            cell_size_m: 0.05,
            border_m: 4.0,
            max_slope_deg: 30.0,
            max_step_height_m: 0.20,
            step_depth_m: 0.35,
            max_obstacle_height_m: 0.15,
            rough_noise_m: 0.04,
            seed: 1,
        }
    }
}

/// Stair riser height at a difficulty in [0, 1], m.
fn step_height_m(c: &TerrainConfig, difficulty: f32) -> f32 {
    0.05 + (c.max_step_height_m - 0.05) * difficulty
}

/// Block height at a difficulty in [0, 1], m.
fn obstacle_height_m(c: &TerrainConfig, difficulty: f32) -> f32 {
    0.03 + (c.max_obstacle_height_m - 0.03) * difficulty
}

/// A generated terrain.
#[derive(Clone, Debug)]
pub struct Terrain {
    /// The settings it was made from.
    pub config: TerrainConfig,
    /// Grid points along x.
    pub nx: usize,
    /// Grid points along y.
    pub ny: usize,
    /// Heights, x-major (`ix * ny + iy`), m. Empty for a flat plane.
    pub heights_m: Vec<f32>,
}

impl Terrain {
    /// Generates the terrain described by `config`.
    pub fn generate(config: &TerrainConfig) -> Self {
        if !config.tiles {
            return Self {
                config: config.clone(),
                nx: 0,
                ny: 0,
                heights_m: Vec::new(),
            };
        }
        let cell = config.cell_size_m;
        let extent_x = config.rows as f32 * config.tile_size_m + 2.0 * config.border_m;
        let extent_y = config.columns.len() as f32 * config.tile_size_m + 2.0 * config.border_m;
        let nx = (extent_x / cell).round() as usize + 1;
        let ny = (extent_y / cell).round() as usize + 1;
        let mut terrain = Self {
            config: config.clone(),
            nx,
            ny,
            heights_m: vec![0.0; nx * ny],
        };
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        for row in 0..config.rows {
            let difficulty = if config.rows > 1 {
                row as f32 / (config.rows - 1) as f32
            } else {
                1.0
            };
            for (col, kind) in config.columns.iter().enumerate() {
                terrain.fill_tile(row, col, *kind, difficulty, &mut rng);
            }
        }
        terrain
    }

    /// A terrain from a height grid (x-major, `ix * ny + iy`, `cell_size_m` apart, the grid
    /// point (0, 0) at the world origin) that is not a tile grid: the evaluation course.
    pub fn from_heights(cell_size_m: f32, nx: usize, ny: usize, heights_m: Vec<f32>) -> Self {
        assert!(
            nx >= 2 && ny >= 2 && heights_m.len() == nx * ny,
            "a height grid needs at least 2 x 2 points"
        );
        let config = TerrainConfig {
            tiles: false,
            rows: 1,
            columns: Vec::new(),
            cell_size_m,
            ..TerrainConfig::default()
        };
        Self {
            config,
            nx,
            ny,
            heights_m,
        }
    }

    /// Difficulty in [0, 1] of a row.
    pub fn difficulty(&self, row: usize) -> f32 {
        if self.config.rows > 1 {
            row as f32 / (self.config.rows - 1) as f32
        } else {
            1.0
        }
    }

    /// The size of a tile's feature at a row, in words ("slope 12 deg down", "steps 0.11 m"),
    /// seen by a robot walking out from the tile's centre.
    pub fn feature(&self, kind: TileKind, row: usize) -> String {
        let c = &self.config;
        let d = self.difficulty(row);
        match kind {
            TileKind::Flat => "flat".into(),
            TileKind::SmoothSlope => format!("slope {:.0} deg down", c.max_slope_deg * d),
            TileKind::SmoothSlopeUp => format!("slope {:.0} deg up", c.max_slope_deg * d),
            TileKind::RoughSlope => format!(
                "slope {:.0} deg up, noise +-{:.2} m",
                c.max_slope_deg * d,
                c.rough_noise_m * (0.5 + d)
            ),
            TileKind::StairsUp | TileKind::StairsDown => {
                format!("steps {:.2} m", step_height_m(c, d))
            }
            TileKind::DiscreteObstacles => format!("blocks +-{:.2} m", obstacle_height_m(c, d)),
        }
    }

    /// World position of the centre of tile (row, col), m.
    pub fn tile_center_m(&self, row: usize, col: usize) -> [f32; 2] {
        if !self.config.tiles {
            return [0.0, 0.0];
        }
        let c = &self.config;
        [
            c.border_m + (row as f32 + 0.5) * c.tile_size_m,
            c.border_m + (col as f32 + 0.5) * c.tile_size_m,
        ]
    }

    fn fill_tile(
        &mut self,
        row: usize,
        col: usize,
        kind: TileKind,
        difficulty: f32,
        rng: &mut ChaCha8Rng,
    ) {
        let c = self.config.clone();
        let [cx, cy] = self.tile_center_m(row, col);
        let half = c.tile_size_m / 2.0;
        let platform_half_m = 1.0;
        let slope = (c.max_slope_deg * difficulty).to_radians().tan();
        let step_h = step_height_m(&c, difficulty);
        let obstacles: Vec<[f32; 5]> = if kind == TileKind::DiscreteObstacles {
            let h = obstacle_height_m(&c, difficulty);
            (0..40)
                .map(|_| {
                    let w = rng.gen_range(0.3..1.0);
                    let l = rng.gen_range(0.3..1.0);
                    let x = cx + rng.gen_range(-half..half);
                    let y = cy + rng.gen_range(-half..half);
                    [x, y, w, l, h * if rng.gen_bool(0.5) { 1.0 } else { -1.0 }]
                })
                .filter(|o| {
                    (o[0] - cx).abs() > platform_half_m + o[2]
                        || (o[1] - cy).abs() > platform_half_m + o[3]
                })
                .collect()
        } else {
            Vec::new()
        };
        // Rough-slope noise on a coarse 0.2 m lattice, interpolated (legged_gym's downsampling).
        const NOISE_CELL_M: f32 = 0.2;
        let noise_n = (c.tile_size_m / NOISE_CELL_M).ceil() as usize + 2;
        let noise: Vec<f32> = if kind == TileKind::RoughSlope {
            (0..noise_n * noise_n)
                .map(|_| rng.gen_range(-1.0..1.0) * c.rough_noise_m)
                .collect()
        } else {
            Vec::new()
        };
        let noise_at = |x: f32, y: f32| -> f32 {
            let fx = ((x - (cx - half)) / NOISE_CELL_M).clamp(0.0, (noise_n - 2) as f32);
            let fy = ((y - (cy - half)) / NOISE_CELL_M).clamp(0.0, (noise_n - 2) as f32);
            let (i, j) = (fx as usize, fy as usize);
            let (tx, ty) = (fx - i as f32, fy - j as f32);
            let n = |a: usize, b: usize| noise[a * noise_n + b];
            (n(i, j) * (1.0 - ty) + n(i, j + 1) * ty) * (1.0 - tx)
                + (n(i + 1, j) * (1.0 - ty) + n(i + 1, j + 1) * ty) * tx
        };
        let (ix0, ix1) = self.index_range(cx - half, cx + half, true);
        let (iy0, iy1) = self.index_range(cy - half, cy + half, false);
        for ix in ix0..ix1 {
            for iy in iy0..iy1 {
                let x = ix as f32 * c.cell_size_m;
                let y = iy as f32 * c.cell_size_m;
                // Chebyshev distance from the centre platform's edge.
                let d = ((x - cx).abs().max((y - cy).abs()) - platform_half_m).max(0.0);
                let d = d.min(half - platform_half_m - 0.5);
                let h = match kind {
                    TileKind::Flat => 0.0,
                    TileKind::SmoothSlope => -slope * d,
                    TileKind::SmoothSlopeUp => slope * d,
                    TileKind::RoughSlope => slope * d + noise_at(x, y) * (0.5 + difficulty),
                    TileKind::StairsUp => step_h * (d / c.step_depth_m).ceil(),
                    TileKind::StairsDown => -step_h * (d / c.step_depth_m).ceil(),
                    TileKind::DiscreteObstacles => obstacles
                        .iter()
                        .filter(|o| (x - o[0]).abs() < o[2] / 2.0 && (y - o[1]).abs() < o[3] / 2.0)
                        .map(|o| o[4])
                        .next()
                        .unwrap_or(0.0),
                };
                self.heights_m[ix * self.ny + iy] = h;
            }
        }
    }

    fn index_range(&self, lo_m: f32, hi_m: f32, along_x: bool) -> (usize, usize) {
        let n = if along_x { self.nx } else { self.ny };
        let cell = self.config.cell_size_m;
        let lo = ((lo_m / cell).ceil().max(0.0) as usize).min(n);
        let hi = ((hi_m / cell).ceil().max(0.0) as usize).min(n);
        (lo, hi)
    }

    /// Terrain height at a world position (bilinear between grid points), m.
    pub fn height_at_m(&self, x_m: f32, y_m: f32) -> f32 {
        if self.heights_m.is_empty() {
            return 0.0;
        }
        let cell = self.config.cell_size_m;
        let fx = (x_m / cell).clamp(0.0, (self.nx - 1) as f32 - 1e-3);
        let fy = (y_m / cell).clamp(0.0, (self.ny - 1) as f32 - 1e-3);
        let (ix, iy) = (fx as usize, fy as usize);
        let (tx, ty) = (fx - ix as f32, fy - iy as f32);
        let h = |i: usize, j: usize| self.heights_m[i * self.ny + j];
        let h0 = h(ix, iy) * (1.0 - ty) + h(ix, iy + 1) * ty;
        let h1 = h(ix + 1, iy) * (1.0 - ty) + h(ix + 1, iy + 1) * ty;
        h0 * (1.0 - tx) + h1 * tx
    }

    /// The rapier collider of the ground: a thick box for a flat plane, otherwise a
    /// heightfield (parry's heightfields are y-up: rotated so heights point along z).
    pub fn collider(&self) -> Collider {
        if self.heights_m.is_empty() {
            return ColliderBuilder::cuboid(500.0, 500.0, 0.5)
                .translation(Vector::new(0.0, 0.0, -0.5))
                .friction(GROUND_FRICTION)
                .build();
        }
        let cell = self.config.cell_size_m;
        // parry grid (row i along local z, column j along local x); local z = -world y.
        let mut grid = rapier3d::parry::utils::Array2::zeros(self.ny, self.nx);
        for ix in 0..self.nx {
            for iy in 0..self.ny {
                grid[(self.ny - 1 - iy, ix)] = self.heights_m[ix * self.ny + iy];
            }
        }
        let size_x = (self.nx - 1) as f32 * cell;
        let size_y = (self.ny - 1) as f32 * cell;
        ColliderBuilder::heightfield(grid, Vector::new(size_x, 1.0, size_y))
            .rotation(Vector::new(std::f32::consts::FRAC_PI_2, 0.0, 0.0))
            .translation(Vector::new(size_x / 2.0, size_y / 2.0, 0.0))
            .friction(GROUND_FRICTION)
            .build()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiles() -> Terrain {
        Terrain::generate(&TerrainConfig {
            tiles: true,
            rows: 4,
            ..Default::default()
        })
    }

    #[test]
    fn hardest_row_has_20_cm_stairs_and_30_deg_slopes() {
        let t = tiles();
        let cols = &t.config.columns;
        let row = t.config.rows - 1;
        let up = cols.iter().position(|k| *k == TileKind::StairsUp).unwrap();
        let [cx, cy] = t.tile_center_m(row, up);
        // Walk outward along x across several steps; each riser is 0.20 m.
        let mut heights: Vec<f32> = (0..60)
            .map(|k| t.height_at_m(cx + 1.0 + k as f32 * 0.05, cy))
            .collect();
        heights.dedup_by(|a, b| (*a - *b).abs() < 1e-4);
        let risers: Vec<f32> = heights
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| d.abs() > 0.05)
            .collect();
        assert!(!risers.is_empty());
        for r in risers {
            assert!((r - 0.20).abs() < 1e-3, "riser {r}");
        }
        let slope = cols
            .iter()
            .position(|k| *k == TileKind::SmoothSlope)
            .unwrap();
        let [cx, cy] = t.tile_center_m(row, slope);
        let dh = t.height_at_m(cx + 2.0, cy) - t.height_at_m(cx + 3.0, cy);
        assert!(
            (dh.atan().to_degrees() - 30.0).abs() < 0.5,
            "{}",
            dh.atan().to_degrees()
        );
    }

    #[test]
    fn smooth_uphill_slope_climbs_outward_at_the_rows_angle() {
        let t = Terrain::generate(&TerrainConfig {
            tiles: true,
            rows: 4,
            columns: vec![TileKind::SmoothSlopeUp],
            ..Default::default()
        });
        for row in 0..4 {
            let [cx, cy] = t.tile_center_m(row, 0);
            let want_deg = t.config.max_slope_deg * t.difficulty(row);
            // Outward along +x, -x and +y: every heading from the centre climbs.
            for (dx, dy) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0)] {
                let h = |r: f32| t.height_at_m(cx + dx * r, cy + dy * r);
                let deg = (h(3.0) - h(2.0)).atan().to_degrees();
                assert!(
                    (deg - want_deg).abs() < 0.05,
                    "row {row}: {deg} deg, want {want_deg}"
                );
            }
            assert_eq!(t.height_at_m(cx, cy), 0.0, "the centre platform is level");
            assert!(t.feature(TileKind::SmoothSlopeUp, row).ends_with("deg up"));
        }
    }

    #[test]
    fn easiest_row_is_gentle() {
        let t = tiles();
        let slope = t
            .config
            .columns
            .iter()
            .position(|k| *k == TileKind::SmoothSlope)
            .unwrap();
        let [cx, cy] = t.tile_center_m(0, slope);
        assert!((t.height_at_m(cx + 3.0, cy)).abs() < 1e-4);
    }

    #[test]
    fn same_seed_same_terrain() {
        assert_eq!(tiles().heights_m, tiles().heights_m);
    }
}

#[cfg(test)]
mod collider_tests {
    use super::*;
    use rapier3d::parry::query::Ray;
    use rapier3d::prelude::Vector;

    #[test]
    fn collider_surface_matches_the_height_lookup() {
        let t = Terrain::generate(&TerrainConfig {
            tiles: true,
            rows: 4,
            ..Default::default()
        });
        let ground = t.collider();
        let mut worst = 0.0f32;
        for row in 0..4 {
            for col in 0..6 {
                let [cx, cy] = t.tile_center_m(row, col);
                for k in 0..400 {
                    // Off-lattice points (a lattice point hides a transposed or shifted grid).
                    let x = cx - 3.0 + (k % 20) as f32 * 0.3137;
                    let y = cy - 3.0 + (k / 20) as f32 * 0.2971;
                    let ray = Ray::new(
                        Vector::new(x, y, 5.0),
                        Vector::new(1e-4, 1e-4, -1.0).normalize(),
                    );
                    // A ray straight down misses parry's heightfield: tilt it by 1e-4.
                    let toi = ground
                        .shape()
                        .cast_ray(ground.position(), &ray, 20.0, true)
                        .expect("ray hits the ground");
                    let z = 5.0 - toi;
                    // Within one cell the two triangles and the bilinear lookup agree where
                    // the cell's corners are level, and differ by less than its corners'
                    // spread (a riser crossing the cell) elsewhere.
                    let cell = t.config.cell_size_m;
                    let (ix, iy) = ((x / cell) as usize, (y / cell) as usize);
                    let corners = [(ix, iy), (ix + 1, iy), (ix, iy + 1), (ix + 1, iy + 1)]
                        .map(|(i, j)| t.heights_m[i * t.ny + j]);
                    let spread = corners.iter().cloned().fold(f32::MIN, f32::max)
                        - corners.iter().cloned().fold(f32::MAX, f32::min);
                    let error = (z - t.height_at_m(x, y)).abs();
                    assert!(
                        error <= spread + 2e-3,
                        "at ({x}, {y}): collider {z} m, lookup {} m",
                        t.height_at_m(x, y)
                    );
                    worst = worst.max(error - spread);
                }
            }
        }
        assert!(
            worst < 2e-3,
            "collider and height lookup differ by {worst} m beyond the cells' spread"
        );
    }
}
