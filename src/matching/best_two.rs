/// The nearest and second-nearest candidates seen so far, for the ratio test.
/// On equal distances the first candidate offered stays the best, and the
/// second distance then equals the best.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BestTwo {
    /// Index and distance of the nearest candidate.
    pub best: Option<(usize, f32)>,
    /// Distance of the second nearest (infinite when there is none).
    pub second: f32,
}

impl Default for BestTwo {
    fn default() -> Self {
        Self {
            best: None,
            second: f32::INFINITY,
        }
    }
}

impl BestTwo {
    /// Offers a candidate.
    pub fn offer(&mut self, index: usize, distance: f32) {
        match self.best {
            Some((_, d)) if distance >= d => {
                if distance < self.second {
                    self.second = distance;
                }
            }
            Some((_, d)) => {
                self.second = d;
                self.best = Some((index, distance));
            }
            None => self.best = Some((index, distance)),
        }
    }

    /// The best candidate when it passes both tests: distance at most
    /// `max_distance`, and (when `ratio` is given) strictly below `ratio`
    /// times the second distance. Ties between best and second therefore fail
    /// any ratio test.
    pub fn accept(&self, max_distance: f32, ratio: Option<f32>) -> Option<(usize, f32)> {
        let (i, d) = self.best?;
        if d > max_distance {
            return None;
        }
        match ratio {
            Some(r) if d >= r * self.second => None,
            _ => Some((i, d)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_first_on_ties_and_tracks_second() {
        let mut b = BestTwo::default();
        b.offer(3, 1.0);
        b.offer(4, 1.0);
        b.offer(5, 2.0);
        assert_eq!(b.best, Some((3, 1.0)));
        assert_eq!(b.second, 1.0);
        assert_eq!(b.accept(10.0, Some(0.9)), None);
        assert_eq!(b.accept(10.0, None), Some((3, 1.0)));
        let mut c = BestTwo::default();
        c.offer(0, 2.0);
        c.offer(1, 0.5);
        assert_eq!((c.best, c.second), (Some((1, 0.5)), 2.0));
        assert_eq!(c.accept(1.0, Some(0.7)), Some((1, 0.5)));
        assert_eq!(c.accept(0.4, Some(0.7)), None);
    }
}
