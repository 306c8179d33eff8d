//! A keyframe database over global descriptors: insert, erase and a
//! brute-force cosine query that scores covisibility groups as ORB-SLAM3
//! does.
//!
//! [`KeyframeDatabase::query`] follows ORB-SLAM3's
//! `KeyFrameDatabase::DetectNBestCandidates` (`src/KeyFrameDatabase.cc`) in
//! spirit, with a cosine similarity in place of the bag-of-words score and of
//! its "shares enough words" preselection:
//! 1. every stored keyframe not in the exclude set (the query keyframe's
//!    covisible keyframes, the caller's choice) gets its similarity `s`, the
//!    dot product of the unit descriptors;
//! 2. as ORB-SLAM3 keeps the keyframes sharing at least 80 % of the best
//!    count of common words, the keyframes with
//!    `s ≥ min_score_ratio · best s` (and `s > 0`) are *scored*;
//! 3. each scored keyframe's group is itself and its best
//!    [`group_size`](QueryOptions::group_size) covisible keyframes
//!    (`GetBestCovisibilityKeyFrames(10)`) that are also scored; the group's
//!    score is the sum of their similarities, and the group is represented
//!    by its most similar keyframe;
//! 4. groups are ranked by their accumulated score, and the best
//!    [`n_best`](QueryOptions::n_best) distinct representatives are returned.
//!
//! Ties are broken by the keyframe id, so the result does not depend on the
//! order of insertion.
//!
//! **Shortlist.** Long descriptors (more than 2 × [`SKETCH_DIM`] values: a
//! raw VLAD has 16,384) also get a count sketch ([`super::sketch`]). When
//! more than [`SHORTLIST`] keyframes are stored, step 1 ranks every
//! keyframe by its sketch and computes the exact similarity of the best
//! [`SHORTLIST`] only; the rest count as unscored. Up to [`SHORTLIST`]
//! keyframes the query is exact; above, it differs from the brute-force
//! one only when a keyframe's sketch rank is off by hundreds or when more
//! than [`SHORTLIST`] keyframes reach the score cut.

use std::collections::{HashMap, HashSet};
use std::hash::Hash;

use super::global_descriptor::dot;
use super::sketch::{CountSketch, SKETCH_DIM};
use super::PlaceError;

/// Keyframes whose exact similarity a query computes when their sketches
/// rank the database (see the module's docs).
pub const SHORTLIST: usize = 256;

/// How many candidates a query returns, and how groups are formed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryOptions {
    /// Candidates returned, at most (ORB-SLAM3 asks for 3).
    pub n_best: usize,
    /// Covisible keyframes per group (ORB-SLAM3: 10).
    pub group_size: usize,
    /// A keyframe is scored when its similarity is at least this fraction of
    /// the best one (ORB-SLAM3's `minCommonWords = 0.8 · maxCommonWords`).
    pub min_score_ratio: f32,
}

impl Default for QueryOptions {
    /// 3 candidates, groups of 10, ratio 0.8.
    fn default() -> Self {
        Self {
            n_best: 3,
            group_size: 10,
            min_score_ratio: 0.8,
        }
    }
}

/// A keyframe a query returned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate<K> {
    /// The keyframe: the most similar one of its group.
    pub keyframe: K,
    /// Its cosine similarity with the query.
    pub score: f32,
    /// Its group's accumulated similarity, which ranked it.
    pub group_score: f32,
}

/// One global descriptor per keyframe, keyed by `K`.
#[derive(Debug, Clone)]
pub struct KeyframeDatabase<K> {
    dim: usize,
    ids: Vec<K>,
    data: Vec<f32>,
    slot: HashMap<K, usize>,
    /// The sketch, for long descriptors, and the stored sketches.
    sketch: Option<CountSketch>,
    sketches: Vec<f32>,
}

impl<K: Copy + Eq + Hash + Ord> KeyframeDatabase<K> {
    /// An empty database of descriptors of `dim` values (> 0).
    pub fn new(dim: usize) -> Result<Self, PlaceError> {
        if dim == 0 {
            return Err(PlaceError::invalid("descriptor length", 0, "at least 1"));
        }
        Ok(Self {
            dim,
            ids: Vec::new(),
            data: Vec::new(),
            slot: HashMap::new(),
            sketch: (dim > 2 * SKETCH_DIM).then(|| CountSketch::new(dim)),
            sketches: Vec::new(),
        })
    }

    /// Values per descriptor.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of keyframes stored.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// The stored keyframes, in storage order.
    pub fn keyframes(&self) -> impl Iterator<Item = K> + '_ {
        self.ids.iter().copied()
    }

    /// True when no keyframe is stored.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// True when `keyframe` is stored.
    pub fn contains(&self, keyframe: K) -> bool {
        self.slot.contains_key(&keyframe)
    }

    /// Stores `keyframe`'s descriptor (unit-norm, [`dim`](Self::dim) values),
    /// replacing the one it had.
    pub fn insert(&mut self, keyframe: K, descriptor: &[f32]) -> Result<(), PlaceError> {
        if descriptor.len() != self.dim {
            return Err(PlaceError::RowLength {
                expected: self.dim,
                actual: descriptor.len(),
            });
        }
        if let Some(&i) = self.slot.get(&keyframe) {
            self.data[i * self.dim..(i + 1) * self.dim].copy_from_slice(descriptor);
            if let Some(sketch) = &self.sketch {
                let mut row = Vec::with_capacity(SKETCH_DIM);
                sketch.push(descriptor, &mut row);
                self.sketches[i * SKETCH_DIM..(i + 1) * SKETCH_DIM].copy_from_slice(&row);
            }
        } else {
            self.slot.insert(keyframe, self.ids.len());
            self.ids.push(keyframe);
            self.data.extend_from_slice(descriptor);
            if let Some(sketch) = &self.sketch {
                sketch.push(descriptor, &mut self.sketches);
            }
        }
        Ok(())
    }

    /// The stored descriptor of `keyframe`.
    pub fn descriptor(&self, keyframe: K) -> Option<&[f32]> {
        let i = *self.slot.get(&keyframe)?;
        self.data.get(i * self.dim..(i + 1) * self.dim)
    }

    /// Moves every entry of `other` into this database (a map merge);
    /// an entry of a keyframe stored in both takes `other`'s descriptor.
    pub fn absorb(&mut self, other: Self) -> Result<(), PlaceError> {
        for (i, k) in other.ids.iter().enumerate() {
            let row = other.data.get(i * other.dim..(i + 1) * other.dim);
            self.insert(*k, row.unwrap_or_default())?;
        }
        Ok(())
    }

    /// Removes `keyframe` (a culled keyframe). Returns whether it was stored.
    pub fn erase(&mut self, keyframe: K) -> bool {
        let Some(i) = self.slot.remove(&keyframe) else {
            return false;
        };
        let last = self.ids.len() - 1;
        if i != last {
            let moved = self.ids[last];
            self.ids[i] = moved;
            self.data
                .copy_within(last * self.dim..(last + 1) * self.dim, i * self.dim);
            if self.sketch.is_some() {
                self.sketches
                    .copy_within(last * SKETCH_DIM..(last + 1) * SKETCH_DIM, i * SKETCH_DIM);
            }
            self.slot.insert(moved, i);
        }
        self.ids.pop();
        self.data.truncate(last * self.dim);
        if self.sketch.is_some() {
            self.sketches.truncate(last * SKETCH_DIM);
        }
        true
    }

    /// The cosine similarity of `descriptor` with every stored keyframe not
    /// in `exclude`, in storage order.
    pub fn similarities(
        &self,
        descriptor: &[f32],
        exclude: &HashSet<K>,
    ) -> Result<Vec<(K, f32)>, PlaceError> {
        self.check_length(descriptor)?;
        Ok(self
            .ids
            .iter()
            .zip(self.data.chunks_exact(self.dim))
            .filter(|(k, _)| !exclude.contains(k))
            .map(|(&k, row)| (k, dot(descriptor, row)))
            .collect())
    }

    /// Fails unless `descriptor` has [`Self::dim`] values.
    fn check_length(&self, descriptor: &[f32]) -> Result<(), PlaceError> {
        if descriptor.len() != self.dim {
            return Err(PlaceError::RowLength {
                expected: self.dim,
                actual: descriptor.len(),
            });
        }
        Ok(())
    }

    /// The exact similarity of the [`SHORTLIST`] keyframes not in
    /// `exclude` whose sketches are most similar to `descriptor`'s.
    fn shortlisted_similarities(
        &self,
        sketch: &CountSketch,
        descriptor: &[f32],
        exclude: &HashSet<K>,
    ) -> Result<Vec<(K, f32)>, PlaceError> {
        self.check_length(descriptor)?;
        let mut query = Vec::with_capacity(SKETCH_DIM);
        sketch.push(descriptor, &mut query);
        let mut ranked: Vec<(f32, usize)> = self
            .sketches
            .chunks_exact(SKETCH_DIM)
            .enumerate()
            .filter(|(i, _)| !exclude.contains(&self.ids[*i]))
            .map(|(i, row)| (dot(&query, row), i))
            .collect();
        let by_score = |a: &(f32, usize), b: &(f32, usize)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
        if ranked.len() > SHORTLIST {
            ranked.select_nth_unstable_by(SHORTLIST - 1, by_score);
            ranked.truncate(SHORTLIST);
        }
        Ok(ranked
            .into_iter()
            .filter_map(|(_, i)| {
                let row = self.data.get(i * self.dim..(i + 1) * self.dim)?;
                Some((self.ids[i], dot(descriptor, row)))
            })
            .collect())
    }

    /// The best candidates for `descriptor` (see the module's docs), best
    /// first. `covisible(k)` gives keyframe `k`'s covisible keyframes, best
    /// first; keyframes not stored are ignored.
    pub fn query<F>(
        &self,
        descriptor: &[f32],
        exclude: &HashSet<K>,
        covisible: F,
        options: &QueryOptions,
    ) -> Result<Vec<Candidate<K>>, PlaceError>
    where
        F: Fn(K) -> Vec<K>,
    {
        if !(options.min_score_ratio.is_finite() && (0.0..=1.0).contains(&options.min_score_ratio))
        {
            return Err(PlaceError::invalid(
                "min_score_ratio",
                options.min_score_ratio,
                "a number in [0, 1]",
            ));
        }
        let all = match &self.sketch {
            Some(sketch) if self.ids.len() > SHORTLIST => {
                self.shortlisted_similarities(sketch, descriptor, exclude)?
            }
            _ => self.similarities(descriptor, exclude)?,
        };
        let best = all
            .iter()
            .map(|&(_, s)| s)
            .fold(f32::NEG_INFINITY, f32::max);
        if options.n_best == 0 || best.is_nan() || best <= 0.0 {
            return Ok(Vec::new());
        }
        let cut = options.min_score_ratio * best;
        let scored: HashMap<K, f32> = all.into_iter().filter(|&(_, s)| s >= cut).collect();
        let mut groups: Vec<(f32, K, f32)> = scored
            .iter()
            .map(|(&k, &s)| {
                let (mut acc, mut rep, mut rep_score) = (s, k, s);
                for n in covisible(k).into_iter().take(options.group_size) {
                    if n == k {
                        continue;
                    }
                    if let Some(&sn) = scored.get(&n) {
                        acc += sn;
                        if sn > rep_score || (sn == rep_score && n < rep) {
                            rep = n;
                            rep_score = sn;
                        }
                    }
                }
                (acc, rep, rep_score)
            })
            .collect();
        // Best group first; among equal groups the lower representative id.
        groups.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut taken = HashSet::new();
        let mut out = Vec::with_capacity(options.n_best);
        for (acc, rep, rep_score) in groups {
            if out.len() == options.n_best {
                break;
            }
            if taken.insert(rep) {
                out.push(Candidate {
                    keyframe: rep,
                    score: rep_score,
                    group_score: acc,
                });
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::place::global_descriptor::l2_normalise;
    use crate::place::SeededRng;
    use std::collections::BTreeMap;

    fn unit(rng: &mut SeededRng, dim: usize) -> Vec<f32> {
        let mut v: Vec<f32> = (0..dim).map(|_| rng.next_unit() as f32 - 0.5).collect();
        l2_normalise(&mut v);
        v
    }

    /// The query written out plainly over a `BTreeMap`, for comparison.
    fn reference(
        stored: &BTreeMap<u32, Vec<f32>>,
        q: &[f32],
        exclude: &HashSet<u32>,
        covis: &dyn Fn(u32) -> Vec<u32>,
        o: &QueryOptions,
    ) -> Vec<(u32, f32)> {
        let sims: BTreeMap<u32, f32> = stored
            .iter()
            .filter(|(k, _)| !exclude.contains(k))
            .map(|(&k, v)| (k, dot(q, v)))
            .collect();
        let best = sims.values().cloned().fold(f32::NEG_INFINITY, f32::max);
        if best <= 0.0 {
            return vec![];
        }
        let scored: BTreeMap<u32, f32> = sims
            .into_iter()
            .filter(|(_, s)| *s >= o.min_score_ratio * best)
            .collect();
        let mut groups = vec![];
        for (&k, &s) in &scored {
            let mut members = vec![(k, s)];
            for n in covis(k).into_iter().take(o.group_size) {
                if n != k {
                    if let Some(&sn) = scored.get(&n) {
                        members.push((n, sn));
                    }
                }
            }
            let acc: f32 = members.iter().map(|m| m.1).sum();
            members.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            groups.push((acc, members[0]));
        }
        groups.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1 .0.cmp(&b.1 .0)));
        let mut out: Vec<(u32, f32)> = vec![];
        for (_, m) in groups {
            if out.len() < o.n_best && !out.iter().any(|o| o.0 == m.0) {
                out.push(m);
            }
        }
        out
    }

    #[test]
    fn matches_a_brute_force_reference_with_erasures() {
        for seed in 0..20 {
            let mut rng = SeededRng::new(seed);
            let dim = 16;
            let mut db = KeyframeDatabase::new(dim).unwrap();
            let mut stored = BTreeMap::new();
            for k in 0..120u32 {
                let v = unit(&mut rng, dim);
                db.insert(k, &v).unwrap();
                stored.insert(k, v);
            }
            for _ in 0..30 {
                let k = rng.below(120) as u32;
                assert_eq!(db.erase(k), stored.remove(&k).is_some());
            }
            assert_eq!(db.len(), stored.len());
            let q = unit(&mut rng, dim);
            let exclude: HashSet<u32> = (0..10).map(|_| rng.below(120) as u32).collect();
            // Neighbours on a ring, farthest first for odd keyframes.
            let covis = |k: u32| -> Vec<u32> {
                let mut n: Vec<u32> = (1..=6)
                    .flat_map(|d| [(k + d) % 120, (k + 120 - d) % 120])
                    .collect();
                if k % 2 == 1 {
                    n.reverse();
                }
                n
            };
            let options = QueryOptions {
                n_best: 1 + (seed as usize % 5),
                group_size: 10,
                min_score_ratio: if seed % 2 == 0 { 0.8 } else { 0.3 },
            };
            let got = db.query(&q, &exclude, covis, &options).unwrap();
            let want = reference(&stored, &q, &exclude, &covis, &options);
            let got: Vec<(u32, f32)> = got.iter().map(|c| (c.keyframe, c.score)).collect();
            assert_eq!(got, want, "seed {seed}");
        }
    }

    #[test]
    fn groups_win_over_lone_keyframes_and_exclusion_holds() {
        let mut db = KeyframeDatabase::new(2).unwrap();
        // Keyframe 1 is most similar alone; 10, 11 and 12 form a group.
        db.insert(1, &[1.0, 0.0]).unwrap();
        for (k, a) in [(10, 0.3f32), (11, 0.35), (12, 0.4)] {
            db.insert(k, &[a.cos(), a.sin()]).unwrap();
        }
        db.insert(20, &[0.0, 1.0]).unwrap();
        let covis = |k: i32| -> Vec<i32> {
            match k {
                10..=12 => vec![10, 11, 12],
                _ => vec![],
            }
        };
        let o = QueryOptions {
            n_best: 3,
            group_size: 10,
            min_score_ratio: 0.5,
        };
        let got = db.query(&[1.0, 0.0], &HashSet::new(), covis, &o).unwrap();
        // The group's best member, 10, ranks first; 1 second.
        assert_eq!(got[0].keyframe, 10);
        assert_eq!(got[1].keyframe, 1);
        assert_eq!(got.len(), 2);
        let got = db
            .query(&[1.0, 0.0], &[10, 11, 12].into_iter().collect(), covis, &o)
            .unwrap();
        assert_eq!(got.iter().map(|c| c.keyframe).collect::<Vec<_>>(), vec![1]);
        assert!(db.insert(3, &[1.0]).is_err());
        assert!(db.query(&[1.0], &HashSet::new(), covis, &o).is_err());
        assert!(!db.erase(99));
        // Re-inserting replaces.
        db.insert(1, &[0.0, 1.0]).unwrap();
        assert_eq!(db.len(), 5);
    }

    /// Above [`SHORTLIST`] keyframes of long descriptors the query goes
    /// through the sketches; on a database of places seen several times
    /// (groups of similar descriptors among random ones), with erasures and
    /// re-insertions, it returns what the brute-force reference returns.
    #[test]
    fn shortlisted_queries_match_the_brute_force_reference() {
        let dim = 4 * SKETCH_DIM;
        let mut rng = SeededRng::new(11);
        let mut db = KeyframeDatabase::new(dim).unwrap();
        let mut stored = BTreeMap::new();
        let places: Vec<Vec<f32>> = (0..40).map(|_| unit(&mut rng, dim)).collect();
        for k in 0..1200u32 {
            let mut v = unit(&mut rng, dim);
            if k % 3 == 0 {
                // A view of place k/3 % 40: cosine about 0.7 with it.
                let place = &places[(k as usize / 3) % 40];
                v.iter_mut()
                    .zip(place)
                    .for_each(|(x, p)| *x = 0.7 * p + 0.7 * *x);
                l2_normalise(&mut v);
            }
            db.insert(k, &v).unwrap();
            stored.insert(k, v);
        }
        for k in (0..1200u32).step_by(7) {
            assert!(db.erase(k));
            stored.remove(&k);
        }
        let v = unit(&mut rng, dim);
        db.insert(3, &v).unwrap();
        stored.insert(3, v);
        assert!(db.len() > SHORTLIST);
        let covis = |k: u32| -> Vec<u32> { vec![(k + 3) % 1200, (k + 1197) % 1200] };
        let options = QueryOptions::default();
        for (n, place) in places.iter().enumerate() {
            let mut q = unit(&mut rng, dim);
            q.iter_mut()
                .zip(place)
                .for_each(|(x, p)| *x = 0.7 * p + 0.7 * *x);
            l2_normalise(&mut q);
            let exclude: HashSet<u32> = [n as u32 * 3].into_iter().collect();
            let got = db.query(&q, &exclude, covis, &options).unwrap();
            let want = reference(&stored, &q, &exclude, &covis, &options);
            let got: Vec<(u32, f32)> = got.iter().map(|c| (c.keyframe, c.score)).collect();
            assert_eq!(got, want, "place {n}");
        }
    }
}
