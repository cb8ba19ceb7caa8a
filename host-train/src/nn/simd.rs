//! Element loops compiled for the widest x86 vector unit the CPU has, chosen at run time.
//!
//! The workspace builds for the baseline x86-64 target (SSE2, 4 lanes), so the learner's
//! own element-wise passes (ELU, bias, their gradients) would run at a quarter of an
//! AVX-512 core's width while the matrix products around them (the `gemm` crate) already
//! detect AVX-512 at run time. [`widest`] runs a loop body inside a function compiled with
//! `avx512f` or `avx2`, whichever the CPU has, so the compiler vectorizes the inlined body at
//! that width. Results are bit for bit those of the baseline build: Rust never contracts a
//! multiply and an add into an FMA, and each element sees the same IEEE operations in the
//! same order at every width (tested for each level the machine has).

/// A vector extension a loop can be compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// The build's baseline (SSE2 on x86-64; whatever the target has elsewhere).
    Baseline,
    /// AVX2 (8 f32 lanes).
    Avx2,
    /// AVX-512 F (16 f32 lanes).
    Avx512,
}

impl Level {
    /// The widest level this CPU supports.
    pub fn detected() -> Level {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f") {
                return Level::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") {
                return Level::Avx2;
            }
        }
        Level::Baseline
    }

    /// Every level this CPU can run, baseline first.
    #[cfg(test)]
    pub fn available() -> Vec<Level> {
        let widest = Level::detected();
        [Level::Baseline, Level::Avx2, Level::Avx512]
            .into_iter()
            .filter(|&l| l as u8 <= widest as u8)
            .collect()
    }
}

/// A loop to compile once per [`Level`]. Implement [`Loop::run`] with `#[inline(always)]`
/// (and keep the element functions it calls `#[inline(always)]` or small), so that its body
/// is inlined into each level's copy and vectorized at that width; a closure would stay a
/// separate function compiled for the baseline.
pub trait Loop {
    /// What the loop returns.
    type Output;
    /// The loop.
    fn run(self) -> Self::Output;
}

/// Runs `body` compiled for the widest level this CPU has (see the module docs).
#[inline(always)]
pub fn widest<L: Loop>(body: L) -> L::Output {
    at(Level::detected(), body)
}

/// Runs `body` compiled for `level`, which must be one [`Level::available`] lists (a level
/// the CPU lacks runs at the baseline instead).
#[inline(always)]
pub fn at<L: Loop>(level: Level, body: L) -> L::Output {
    #[cfg(target_arch = "x86_64")]
    {
        match level {
            // SAFETY: the CPU has AVX-512 F (checked here; detection is cached by std).
            Level::Avx512 if std::is_x86_feature_detected!("avx512f") => unsafe {
                x86::avx512(body)
            },
            // SAFETY: as above, AVX2.
            Level::Avx2 if std::is_x86_feature_detected!("avx2") => unsafe { x86::avx2(body) },
            _ => body.run(),
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = level;
        body.run()
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::Loop;

    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn avx512<L: Loop>(body: L) -> L::Output {
        body.run()
    }

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn avx2<L: Loop>(body: L) -> L::Output {
        body.run()
    }
}

/// `out[i] = f(x[i])`.
pub struct Map1<'a, T, F> {
    pub out: &'a mut [std::mem::MaybeUninit<T>],
    pub x: &'a [T],
    pub f: &'a F,
}

impl<T: Copy, F: Fn(T) -> T> Loop for Map1<'_, T, F> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        for (o, &v) in self.out.iter_mut().zip(self.x) {
            o.write((self.f)(v));
        }
    }
}

/// `out[i] = f(a[i], b[i])`.
pub struct Map2<'a, T, F> {
    pub out: &'a mut [std::mem::MaybeUninit<T>],
    pub a: &'a [T],
    pub b: &'a [T],
    pub f: &'a F,
}

impl<T: Copy, F: Fn(T, T) -> T> Loop for Map2<'_, T, F> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        for ((o, &x), &y) in self.out.iter_mut().zip(self.a).zip(self.b) {
            o.write((self.f)(x, y));
        }
    }
}

/// `out[r, j] = f(x[r, j] + b[j])` over the rows of `x` (each `b.len()` long).
pub struct MapRows<'a, T, F> {
    pub out: &'a mut [std::mem::MaybeUninit<T>],
    pub x: &'a [T],
    pub b: &'a [T],
    pub f: &'a F,
}

impl<T: Copy + std::ops::Add<Output = T>, F: Fn(T) -> T> Loop for MapRows<'_, T, F> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let n = self.b.len();
        for (o, c) in self.out.chunks_exact_mut(n).zip(self.x.chunks_exact(n)) {
            for ((o, &x), &b) in o.iter_mut().zip(c).zip(self.b) {
                o.write((self.f)(x + b));
            }
        }
    }
}

/// `out[r, j] = (x[r, j] - mean[j]) / std[j]` over the rows of `x`.
pub struct NormalizeRows<'a> {
    pub out: &'a mut [std::mem::MaybeUninit<f32>],
    pub x: &'a [f32],
    pub mean: &'a [f32],
    pub std: &'a [f32],
}

impl Loop for NormalizeRows<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let n = self.mean.len();
        for (o, x) in self.out.chunks_exact_mut(n).zip(self.x.chunks_exact(n)) {
            for (((o, &x), &m), &s) in o.iter_mut().zip(x).zip(self.mean).zip(self.std) {
                o.write((x - m) / s);
            }
        }
    }
}

/// `acc[j] += g[r, j]` over the rows of `g`, row after row (each column's order kept).
pub struct AddRows<'a, T> {
    pub acc: &'a mut [T],
    pub g: &'a [T],
}

impl<T: Copy + std::ops::AddAssign> Loop for AddRows<'_, T> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let n = self.acc.len();
        for row in self.g.chunks_exact(n) {
            for (a, &x) in self.acc.iter_mut().zip(row) {
                *a += x;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_ordered_and_the_baseline_is_always_there() {
        let levels = Level::available();
        assert_eq!(levels[0], Level::Baseline);
        assert_eq!(*levels.last().unwrap(), Level::detected());
        let mut acc = [1.0f32, 2.0];
        at(
            Level::Avx512,
            AddRows {
                acc: &mut acc,
                g: &[1.0, 1.0, 3.0, 3.0],
            },
        );
        assert_eq!(acc, [5.0, 6.0]);
    }
}
