//! Carrying a checkpoint's terrain curriculum into a run with another tile layout.
//!
//! A checkpoint records each robot's tile as (row, column). Resumed with the same columns
//! and robots, the tiles are restored as they were. With another layout (columns added,
//! repeated or reordered, another number of robots) a column index means another tile kind,
//! so the rows carry over per tile kind instead: robot `i` of the new run stands on column
//! `i % columns` (the environment's own assignment) and takes, in turn, the rows the
//! checkpoint's robots had reached on that kind. A kind the checkpoint did not train on keeps
//! the robot's initial row.

use host_sim::terrain::TileKind;

/// The tiles (row, column) of a resumed run's robots.
///
/// `saved` are the checkpoint's tiles on `saved_columns`; `initial` are the new run's tiles
/// before the restore, on `columns`.
pub fn carry_tiles(
    saved: &[[usize; 2]],
    saved_columns: &[TileKind],
    initial: &[[usize; 2]],
    columns: &[TileKind],
) -> Vec<[usize; 2]> {
    if saved.len() == initial.len() && saved_columns == columns {
        return saved.to_vec();
    }
    // The rows reached on each kind, in robot order, gathered once per column of the new layout.
    let rows_by_column: Vec<Vec<usize>> = columns
        .iter()
        .map(|kind| {
            saved
                .iter()
                .filter(|[_, c]| saved_columns.get(*c) == Some(kind))
                .map(|[row, _]| *row)
                .collect()
        })
        .collect();
    let mut taken = vec![0usize; columns.len()];
    initial
        .iter()
        .enumerate()
        .map(|(i, [initial_row, _])| {
            let column = i % columns.len().max(1);
            let (Some(kind), Some(rows)) = (columns.get(column), rows_by_column.get(column)) else {
                return [*initial_row, column];
            };
            if rows.is_empty() {
                return [*initial_row, column];
            }
            // Kinds repeated in the new layout draw from the same rows, each column in turn.
            let same_kind_before = columns[..column].iter().filter(|k| *k == kind).count();
            let same_kind = columns.iter().filter(|k| *k == kind).count();
            let n = taken[column] * same_kind + same_kind_before;
            taken[column] += 1;
            [rows[n % rows.len()], column]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use TileKind::*;

    #[test]
    fn the_same_layout_restores_every_tile() {
        let cols = [Flat, StairsUp];
        let saved = [[3, 0], [5, 1], [1, 0], [4, 1]];
        let initial = [[0, 0], [1, 1], [2, 0], [0, 1]];
        assert_eq!(carry_tiles(&saved, &cols, &initial, &cols), saved.to_vec());
    }

    #[test]
    fn an_added_column_of_a_known_kind_takes_that_kinds_rows() {
        let old = [Flat, StairsUp];
        let new = [Flat, StairsUp, StairsUp];
        // Flat robots reached rows 1 and 2, stairs robots 4 and 5.
        let saved = [[1, 0], [4, 1], [2, 0], [5, 1]];
        let initial = [[0, 0]; 6];
        let tiles = carry_tiles(&saved, &old, &initial, &new);
        let columns: Vec<usize> = tiles.iter().map(|t| t[1]).collect();
        assert_eq!(columns, vec![0, 1, 2, 0, 1, 2]);
        let flat_rows: Vec<usize> = tiles.iter().filter(|t| t[1] == 0).map(|t| t[0]).collect();
        assert_eq!(flat_rows, vec![1, 2]);
        let mut stairs_rows: Vec<usize> =
            tiles.iter().filter(|t| t[1] != 0).map(|t| t[0]).collect();
        stairs_rows.sort();
        assert_eq!(stairs_rows, vec![4, 4, 5, 5]);
    }

    #[test]
    fn a_kind_the_checkpoint_never_saw_keeps_its_initial_row() {
        let old = [Flat];
        let new = [Flat, SmoothSlopeUp];
        let saved = [[3, 0], [3, 0]];
        let initial = [[0, 0], [2, 1], [1, 0]];
        assert_eq!(
            carry_tiles(&saved, &old, &initial, &new),
            vec![[3, 0], [2, 1], [3, 0]]
        );
    }

    #[test]
    fn another_number_of_robots_carries_rows_per_kind() {
        let cols = [Flat, StairsDown];
        let saved = [[2, 0], [5, 1]];
        let initial = [[0, 0]; 4];
        assert_eq!(
            carry_tiles(&saved, &cols, &initial, &cols),
            vec![[2, 0], [5, 1], [2, 0], [5, 1]]
        );
    }
}
