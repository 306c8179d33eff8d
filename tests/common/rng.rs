//! The tests' seeded random numbers: the library's SplitMix64
//! (`spslam::dataset::synthetic::SplitMix64`) plus the draws the optimisation
//! tests and benches need.
#![allow(dead_code)]

use nalgebra::{SVector, Vector3};
use spslam::dataset::synthetic::SplitMix64;

/// A seeded generator: the same seed gives the same stream.
#[derive(Debug, Clone)]
pub struct Rng(SplitMix64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(SplitMix64::new(seed))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0.next_unit()
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform integer in [lo, hi].
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.next_u64() % (hi - lo + 1) as u64) as usize
    }

    /// Standard normal (Box–Muller on `max(u1, 1e-300)`).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// A vector of independent normals times `sigma`.
    pub fn normal3(&mut self, sigma: f64) -> Vector3<f64> {
        Vector3::new(self.normal(), self.normal(), self.normal()) * sigma
    }

    /// A vector of independent normals scaled per component by `sigmas`.
    pub fn normal_vector<const N: usize>(&mut self, sigmas: &SVector<f64, N>) -> SVector<f64, N> {
        SVector::<f64, N>::from_fn(|i, _| self.normal() * sigmas[i])
    }
}
