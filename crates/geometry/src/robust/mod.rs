//! A generic robust estimator of the RANSAC family: MSAC scoring, local optimisation and
//! adaptive termination, reproducible from a fixed seed.
//!
//! An estimation problem implements [`Estimator`]: how many data it has, how large a
//! minimal sample is, a minimal solver that returns *every* model of a sample (none for a
//! degenerate sample), a squared residual per datum and, optionally, a refinement of a model
//! on a set of inliers. [`ransac`] then runs the loop:
//!
//! 1. draw a minimal sample of distinct indices (ChaCha8 from [`RansacOptions::seed`]);
//! 2. score each model by the truncated sum `Σᵢ min(rᵢ², t²)` (MSAC, lower is better;
//!    `t` = [`RansacOptions::inlier_threshold`]), stopping the sum as soon as it exceeds the
//!    best score so far (a bad model is rejected after a few data);
//! 3. on every new best model, *local optimisation* (LO): refine it on its inliers with
//!    [`Estimator::refine`], re-score, and keep the refined model when it scores better
//!    (up to [`LO_PASSES`] times while it improves);
//! 4. stop after `k = log(1 − confidence) / log(1 − w^s)` iterations, `w` the inlier ratio
//!    of the best model and `s` the sample size (bounded by the minimum and maximum
//!    iterations of the options);
//! 5. refine the best model once more on its final inliers.
//!
//! The same input and options give the same result.
//!
//! # References
//! - M. A. Fischler, R. C. Bolles, "Random sample consensus", Comm. ACM 24(6), 1981.
//! - P. H. S. Torr, A. Zisserman, "MLESAC: a new robust estimator with application to
//!   estimating image geometry", CVIU 78(1), 2000 (the truncated quadratic score, MSAC).
//! - O. Chum, J. Matas, J. Kittler, "Locally optimized RANSAC", DAGM 2003.
//! - V. Larsson et al., PoseLib (`ransac_impl.h`): the structure of the loop (LO on every
//!   new best, early-terminated scoring, dynamic iteration bound).
//!
//! # Example
//! A line `y = a x + b` through points with 40 % gross outliers:
//! ```
//! use vgps_geometry::robust::{Estimator, RansacOptions, ransac};
//!
//! struct Line(Vec<(f64, f64)>);
//! impl Estimator for Line {
//!     type Model = (f64, f64);
//!     fn sample_size(&self) -> usize { 2 }
//!     fn num_data(&self) -> usize { self.0.len() }
//!     fn generate_models(&self, sample: &[usize], models: &mut Vec<(f64, f64)>) {
//!         let ((x0, y0), (x1, y1)) = (self.0[sample[0]], self.0[sample[1]]);
//!         if (x1 - x0).abs() > 1e-12 {
//!             let a = (y1 - y0) / (x1 - x0);
//!             models.push((a, y0 - a * x0));
//!         }
//!     }
//!     fn residual2(&self, m: &(f64, f64), i: usize) -> f64 {
//!         let (x, y) = self.0[i];
//!         (y - m.0 * x - m.1).powi(2)
//!     }
//! }
//! let data: Vec<(f64, f64)> = (0..50)
//!     .map(|i| {
//!         let x = i as f64;
//!         if i % 5 < 2 { (x, 100.0 - 3.0 * x) } else { (x, 2.0 * x + 1.0) }
//!     })
//!     .collect();
//! let options = RansacOptions { inlier_threshold: 0.1, ..RansacOptions::default() };
//! let result = ransac(&Line(data), &options).unwrap();
//! assert!((result.model.0 - 2.0).abs() < 1e-9 && (result.model.1 - 1.0).abs() < 1e-9);
//! assert_eq!(result.n_inliers, 30);
//! ```

pub mod absolute_pose;

pub use absolute_pose::{
    AbsolutePoseEstimator, AbsolutePoseOptions, PositionPrior, estimate_absolute_pose,
};

use rand::{RngExt, SeedableRng};
use thiserror::Error;

/// Default [`RansacOptions::confidence`]: the probability that at least one all-inlier
/// sample was drawn when the loop stops.
pub const DEFAULT_CONFIDENCE: f64 = 0.9999;

/// Default [`RansacOptions::max_iterations`].
pub const DEFAULT_MAX_ITERATIONS: usize = 10_000;

/// Default [`RansacOptions::min_iterations`].
pub const DEFAULT_MIN_ITERATIONS: usize = 10;

/// Default [`RansacOptions::inlier_threshold`], in the units of the residual (for the
/// problems of this crate, which normalise their residuals by the standard deviation of
/// the noise, 5 σ).
pub const DEFAULT_INLIER_THRESHOLD: f64 = 5.0;

/// Default [`RansacOptions::seed`] (fixed: the same input gives the same result).
pub const DEFAULT_SEED: u64 = 0x7267_7073_5f72_616e;

/// Most refine / re-score passes of one local optimisation (stops early when a pass does
/// not improve the score).
pub const LO_PASSES: usize = 2;

/// Most draws of one minimal sample before giving up on distinct indices (only reachable
/// with a broken random source; the data are at least the sample size).
const MAX_SAMPLE_DRAWS: usize = 1_000;

/// An estimation problem for [`ransac`].
///
/// Data are referred to by their index in `0..num_data()`.
pub trait Estimator {
    /// The estimated model (e.g. a pose).
    type Model: Clone;

    /// Size of a minimal sample (e.g. 3 for P3P).
    fn sample_size(&self) -> usize;

    /// Number of data.
    fn num_data(&self) -> usize;

    /// Pushes every model consistent with the minimal sample `sample` (distinct indices)
    /// into `models` (which arrives empty); pushes nothing for a degenerate sample.
    fn generate_models(&self, sample: &[usize], models: &mut Vec<Self::Model>);

    /// Squared residual of datum `index` under `model`, in the units of
    /// [`RansacOptions::inlier_threshold`] squared. May be `f64::INFINITY` (e.g. a point
    /// behind the camera); must not be NaN.
    fn residual2(&self, model: &Self::Model, index: usize) -> f64;

    /// A model refined on the data `inliers` (at least a minimal sample), starting from
    /// `model`; `None` when no refinement is available or it failed. The default has none
    /// (plain MSAC without local optimisation).
    fn refine(&self, model: &Self::Model, inliers: &[usize]) -> Option<Self::Model> {
        let _ = (model, inliers);
        None
    }
}

/// Options of [`ransac`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RansacOptions {
    /// Inlier threshold `t` on the residual (the square root of
    /// [`Estimator::residual2`]); positive. Default [`DEFAULT_INLIER_THRESHOLD`].
    pub inlier_threshold: f64,
    /// Probability in (0, 1) that an all-inlier sample has been drawn when the loop stops.
    /// Default [`DEFAULT_CONFIDENCE`].
    pub confidence: f64,
    /// Fewest iterations (samples drawn). Default [`DEFAULT_MIN_ITERATIONS`].
    pub min_iterations: usize,
    /// Most iterations. Default [`DEFAULT_MAX_ITERATIONS`].
    pub max_iterations: usize,
    /// Local optimisation on every new best model and on the final model. Default true.
    pub local_optimization: bool,
    /// Seed of the sampler. Default [`DEFAULT_SEED`].
    pub seed: u64,
}

impl Default for RansacOptions {
    fn default() -> Self {
        Self {
            inlier_threshold: DEFAULT_INLIER_THRESHOLD,
            confidence: DEFAULT_CONFIDENCE,
            min_iterations: DEFAULT_MIN_ITERATIONS,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            local_optimization: true,
            seed: DEFAULT_SEED,
        }
    }
}

/// The result of [`ransac`].
#[derive(Clone, Debug, PartialEq)]
pub struct RansacResult<M> {
    /// The best model (after the final refinement).
    pub model: M,
    /// Per datum: whether its residual is within the threshold under `model`.
    pub inliers: Vec<bool>,
    /// Number of inliers.
    pub n_inliers: usize,
    /// Samples drawn.
    pub iterations: usize,
    /// MSAC score of `model`: `Σᵢ min(rᵢ², t²)` (lower is better).
    pub score: f64,
    /// Models generated by the minimal solver and scored.
    pub models_scored: usize,
    /// Local optimisations run (each up to [`LO_PASSES`] refinements).
    pub local_optimizations: usize,
}

/// Why [`ransac`] gave no model.
#[derive(Clone, Copy, Debug, Error, PartialEq)]
pub enum RansacError {
    /// Fewer data than a minimal sample.
    #[error("{available} data, a minimal sample needs {needed}")]
    TooFewData {
        /// Number of data.
        available: usize,
        /// Sample size.
        needed: usize,
    },
    /// An option is out of its domain.
    #[error("invalid option {name}: {value}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A datum is unusable (mismatched lengths, a non-finite value).
    #[error("datum {index}: {reason}")]
    InvalidData {
        /// Index of the datum (or the shorter length for a mismatch).
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// No sample gave a model (degenerate data, or every model rejected by the problem).
    #[error("no minimal sample gave a model in {iterations} iterations")]
    NoModel {
        /// Samples drawn.
        iterations: usize,
    },
}

/// Iterations needed to draw, with probability `confidence`, at least one all-inlier sample
/// of size `sample_size` when a fraction `inlier_ratio` of the data are inliers:
/// `⌈log(1 − confidence) / log(1 − w^s)⌉`, saturating at `usize::MAX` for `w = 0`.
///
/// # Example
/// ```
/// // 50 % inliers, three-point samples, 99.99 %: 69 samples.
/// assert_eq!(vgps_geometry::robust::required_iterations(0.5, 3, 0.9999), 69);
/// assert_eq!(vgps_geometry::robust::required_iterations(1.0, 3, 0.9999), 1);
/// ```
pub fn required_iterations(inlier_ratio: f64, sample_size: usize, confidence: f64) -> usize {
    let good = inlier_ratio.clamp(0.0, 1.0).powi(sample_size as i32);
    if good >= 1.0 {
        return 1;
    }
    let denominator = (-good).ln_1p();
    if denominator >= 0.0 || !denominator.is_finite() {
        return usize::MAX;
    }
    let k = ((1.0 - confidence).ln() / denominator).ceil();
    if k.is_finite() && k >= 1.0 {
        if k >= usize::MAX as f64 {
            usize::MAX
        } else {
            k as usize
        }
    } else {
        1
    }
}

/// Scores `model` (MSAC); returns `(score, inlier count)`. Stops summing once the score
/// exceeds `bound` (the returned score is then larger than `bound` but not complete).
#[inline]
fn score_model<E: Estimator + ?Sized>(
    estimator: &E,
    model: &E::Model,
    threshold2: f64,
    bound: f64,
) -> (f64, usize) {
    let mut score = 0.0;
    let mut count = 0;
    for i in 0..estimator.num_data() {
        let r2 = estimator.residual2(model, i);
        if r2 <= threshold2 {
            score += r2;
            count += 1;
        } else {
            score += threshold2;
        }
        if score > bound {
            return (score, count);
        }
    }
    (score, count)
}

/// Indices of the inliers of `model`.
fn inlier_indices<E: Estimator + ?Sized>(
    estimator: &E,
    model: &E::Model,
    threshold2: f64,
    out: &mut Vec<usize>,
) {
    out.clear();
    out.extend((0..estimator.num_data()).filter(|&i| estimator.residual2(model, i) <= threshold2));
}

/// Local optimisation: refine on the inliers, re-score, repeat while it improves. Returns
/// the improved model with its score and count, or `None` when nothing improved.
fn local_optimization<E: Estimator + ?Sized>(
    estimator: &E,
    model: &E::Model,
    score: f64,
    threshold2: f64,
    scratch: &mut Vec<usize>,
) -> Option<(E::Model, f64, usize)> {
    let mut best: Option<(E::Model, f64, usize)> = None;
    let mut current = model.clone();
    let mut current_score = score;
    for _ in 0..LO_PASSES {
        inlier_indices(estimator, &current, threshold2, scratch);
        if scratch.len() < estimator.sample_size() {
            break;
        }
        let Some(refined) = estimator.refine(&current, scratch) else {
            break;
        };
        let (s, c) = score_model(estimator, &refined, threshold2, f64::INFINITY);
        // Scores are never NaN (residuals are not): `>=` is the negation of `<`.
        if s >= current_score {
            break;
        }
        current = refined;
        current_score = s;
        best = Some((current.clone(), s, c));
    }
    best
}

/// Draws `sample.len()` distinct indices in `0..n` (n ≥ sample length).
#[inline]
fn draw_sample<R: rand::Rng + ?Sized>(rng: &mut R, n: usize, sample: &mut [usize]) -> bool {
    for k in 0..sample.len() {
        let mut draws = 0;
        loop {
            let candidate = rng.random_range(0..n);
            if !sample[..k].contains(&candidate) {
                sample[k] = candidate;
                break;
            }
            draws += 1;
            if draws >= MAX_SAMPLE_DRAWS {
                return false;
            }
        }
    }
    true
}

/// Runs the robust estimator on `estimator` (see the [module documentation](self)).
///
/// # Errors
/// [`RansacError::TooFewData`] with fewer data than a minimal sample (or a zero sample
/// size), [`RansacError::InvalidOption`] for a non-positive threshold, a confidence
/// outside (0, 1) or zero maximum iterations, [`RansacError::NoModel`] when no sample gave
/// a model.
pub fn ransac<E: Estimator + ?Sized>(
    estimator: &E,
    options: &RansacOptions,
) -> Result<RansacResult<E::Model>, RansacError> {
    let n = estimator.num_data();
    let s = estimator.sample_size();
    if s == 0 || n < s {
        return Err(RansacError::TooFewData {
            available: n,
            needed: s,
        });
    }
    let t = options.inlier_threshold;
    if !(t.is_finite() && t > 0.0) {
        return Err(RansacError::InvalidOption {
            name: "inlier_threshold",
            value: t,
        });
    }
    if !(options.confidence > 0.0 && options.confidence < 1.0) {
        return Err(RansacError::InvalidOption {
            name: "confidence",
            value: options.confidence,
        });
    }
    if options.max_iterations == 0 {
        return Err(RansacError::InvalidOption {
            name: "max_iterations",
            value: 0.0,
        });
    }
    let threshold2 = t * t;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed);
    let mut sample = vec![0usize; s];
    let mut models: Vec<E::Model> = Vec::new();
    let mut scratch: Vec<usize> = Vec::with_capacity(n);
    let mut best: Option<(E::Model, f64, usize)> = None;
    let mut best_score = f64::INFINITY;
    let mut dynamic_max = options.max_iterations;
    let mut iterations = 0;
    let mut models_scored = 0;
    let mut local_optimizations = 0;
    while iterations < options.max_iterations
        && (iterations < options.min_iterations || iterations < dynamic_max)
    {
        iterations += 1;
        if !draw_sample(&mut rng, n, &mut sample) {
            break;
        }
        models.clear();
        estimator.generate_models(&sample, &mut models);
        for model in &models {
            models_scored += 1;
            let (score, count) = score_model(estimator, model, threshold2, best_score);
            if score >= best_score {
                continue;
            }
            let mut candidate = (model.clone(), score, count);
            if options.local_optimization {
                local_optimizations += 1;
                if let Some(improved) =
                    local_optimization(estimator, model, score, threshold2, &mut scratch)
                {
                    candidate = improved;
                }
            }
            best_score = candidate.1;
            let ratio = candidate.2 as f64 / n as f64;
            dynamic_max = required_iterations(ratio, s, options.confidence);
            best = Some(candidate);
        }
    }
    let Some((mut model, mut score, _)) = best else {
        return Err(RansacError::NoModel { iterations });
    };
    if options.local_optimization
        && let Some((refined, refined_score, _)) =
            local_optimization(estimator, &model, score, threshold2, &mut scratch)
    {
        model = refined;
        score = refined_score;
    }
    let inliers: Vec<bool> = (0..n)
        .map(|i| estimator.residual2(&model, i) <= threshold2)
        .collect();
    let n_inliers = inliers.iter().filter(|&&b| b).count();
    Ok(RansacResult {
        model,
        inliers,
        n_inliers,
        iterations,
        score,
        models_scored,
        local_optimizations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::rng;
    use rand::RngExt;

    /// A 1-D location problem: the model is a number, each datum a number.
    struct Location(Vec<f64>);
    impl Estimator for Location {
        type Model = f64;
        fn sample_size(&self) -> usize {
            1
        }
        fn num_data(&self) -> usize {
            self.0.len()
        }
        fn generate_models(&self, sample: &[usize], models: &mut Vec<f64>) {
            models.push(self.0[sample[0]]);
        }
        fn residual2(&self, m: &f64, i: usize) -> f64 {
            (self.0[i] - m).powi(2)
        }
        fn refine(&self, _: &f64, inliers: &[usize]) -> Option<f64> {
            Some(inliers.iter().map(|&i| self.0[i]).sum::<f64>() / inliers.len() as f64)
        }
    }

    #[test]
    fn required_iterations_matches_the_formula() {
        assert_eq!(required_iterations(0.5, 3, 0.9999), 69);
        assert_eq!(required_iterations(0.9, 3, 0.99), 4);
        assert_eq!(required_iterations(0.0, 3, 0.99), usize::MAX);
        assert_eq!(required_iterations(1.0, 4, 0.99), 1);
        // 10 % inliers: about 9.2 / 1e-3 samples.
        let k = required_iterations(0.1, 3, 0.9999);
        assert!((9200..9220).contains(&k), "{k}");
    }

    #[test]
    fn location_with_outliers_is_found_refined_and_reproducible() {
        let mut r = rng(1);
        let data: Vec<f64> = (0..200)
            .map(|i| {
                if i % 10 < 7 {
                    r.random_range(900.0..1100.0) // outliers: 70 %
                } else {
                    5.0 + 0.01 * (r.random::<f64>() - 0.5)
                }
            })
            .collect();
        let options = RansacOptions {
            inlier_threshold: 0.1,
            ..RansacOptions::default()
        };
        let problem = Location(data.clone());
        let a = ransac(&problem, &options).unwrap();
        assert_eq!(a.n_inliers, 60);
        let mean = (0..200)
            .filter(|i| i % 10 >= 7)
            .map(|i| data[i])
            .sum::<f64>()
            / 60.0;
        // LO made the model the inlier mean (exact), not one sampled datum.
        assert!((a.model - mean).abs() < 1e-12, "{} vs {mean}", a.model);
        assert!(a.local_optimizations >= 1);
        // 30 % inliers with 1-samples at 99.99 %: ⌈ln 1e-4 / ln 0.7⌉ = 26 iterations at most.
        assert!(a.iterations <= 26, "{}", a.iterations);
        assert_eq!(ransac(&problem, &options).unwrap(), a);
        // Without LO the model is a datum.
        let plain = ransac(
            &problem,
            &RansacOptions {
                local_optimization: false,
                ..options
            },
        )
        .unwrap();
        assert!(data.contains(&plain.model));
        assert!(plain.score >= a.score);
    }

    #[test]
    fn bad_options_and_data_are_errors() {
        let problem = Location(vec![]);
        assert_eq!(
            ransac(&problem, &RansacOptions::default()),
            Err(RansacError::TooFewData {
                available: 0,
                needed: 1
            })
        );
        let problem = Location(vec![1.0, 2.0]);
        for bad in [
            RansacOptions {
                inlier_threshold: 0.0,
                ..RansacOptions::default()
            },
            RansacOptions {
                confidence: 1.0,
                ..RansacOptions::default()
            },
            RansacOptions {
                max_iterations: 0,
                ..RansacOptions::default()
            },
        ] {
            assert!(matches!(
                ransac(&problem, &bad),
                Err(RansacError::InvalidOption { .. })
            ));
        }
    }

    /// A problem whose solver never gives a model.
    struct Never;
    impl Estimator for Never {
        type Model = ();
        fn sample_size(&self) -> usize {
            2
        }
        fn num_data(&self) -> usize {
            5
        }
        fn generate_models(&self, _: &[usize], _: &mut Vec<()>) {}
        fn residual2(&self, _: &(), _: usize) -> f64 {
            0.0
        }
    }

    #[test]
    fn degenerate_data_give_no_model_within_the_budget() {
        let options = RansacOptions {
            max_iterations: 37,
            ..RansacOptions::default()
        };
        assert_eq!(
            ransac(&Never, &options),
            Err(RansacError::NoModel { iterations: 37 })
        );
    }
}
