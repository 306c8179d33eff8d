//! Surface appearance: a gray level at each surface point `(u, v)` (metres),
//! box-filtered over the pixel's footprint so that the same point looks the
//! same from every view and distant detail blurs instead of sparkling.

use super::noise::{fade, floor, fractal_noise};
use super::rng::{hash_cell, unit_from_bits};

/// The extent of one pixel on the surface, in metres along `u` and `v`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Width along `u`.
    pub du: f64,
    /// Width along `v`.
    pub dv: f64,
}

impl Footprint {
    /// The larger of the two widths.
    pub fn max(&self) -> f64 {
        self.du.max(self.dv)
    }
}

/// How a surface looks.
#[derive(Debug, Clone, PartialEq)]
pub enum Texture {
    /// One gray level everywhere (a texture-poor surface).
    Flat {
        /// Gray level, 0–255.
        gray: f64,
    },
    /// Discs on a flat background: markers at exactly known positions.
    Markers {
        /// Gray level of the background, 0–255.
        background: f64,
        /// The discs; later ones paint over earlier ones.
        discs: Vec<DiscMarker>,
    },
    /// Random shapes at several scales over smooth shading.
    Procedural(ProceduralTexture),
}

/// A disc of uniform gray on a [`Texture::Markers`] surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscMarker {
    /// Centre, `u` (metres).
    pub u: f64,
    /// Centre, `v` (metres).
    pub v: f64,
    /// Radius (metres).
    pub radius: f64,
    /// Gray level, 0–255.
    pub gray: f64,
}

/// The shape a [`ShapeLayer`] scatters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShapeKind {
    /// Axis-aligned rectangles.
    Rectangle,
    /// Discs.
    Disc,
    /// Rectangles split into a 2×2 checker (X-corners).
    Checker,
}

/// One scale of scattered shapes: the surface is cut into cells of
/// `cell_u × cell_v` metres and each cell holds at most one shape, inside it.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeLayer {
    /// Cell width along `u` (metres).
    pub cell_u: f64,
    /// Cell height along `v` (metres).
    pub cell_v: f64,
    /// Probability that a cell holds a shape.
    pub occupancy: f64,
    /// What is drawn.
    pub kind: ShapeKind,
    /// Smallest shape size, as a fraction of the cell (≤ 0.9).
    pub size_min: f64,
    /// Largest shape size, as a fraction of the cell (≤ 0.9).
    pub size_max: f64,
    /// Centred shapes of one size (`size_max`), like a grid of windows;
    /// otherwise sizes and positions are random.
    pub regular: bool,
    /// Darkest gray level of a shape.
    pub gray_min: f64,
    /// Brightest gray level of a shape.
    pub gray_max: f64,
    /// Left out inside texture-poor zones.
    pub detail: bool,
}

/// Random shapes at several scales over smooth shading, with texture-poor
/// zones where the detail layers are left out.
#[derive(Debug, Clone, PartialEq)]
pub struct ProceduralTexture {
    /// Seed of every random choice on this surface.
    pub seed: u64,
    /// Mean gray level of the bare surface.
    pub base_gray: f64,
    /// Amplitude of the smooth shading (gray levels).
    pub shading: f64,
    /// Longest wavelength of the shading (metres).
    pub shading_wavelength: f64,
    /// Side of the square zones that may be texture-poor (metres).
    pub flat_zone_size: f64,
    /// Share of zones that are texture-poor, 0–1.
    pub flat_zone_fraction: f64,
    /// Shape layers, painted in order (coarse first).
    pub layers: Vec<ShapeLayer>,
}

impl Texture {
    /// The gray level (0–255, not clamped) at `(u, v)`, averaged over `footprint`.
    pub fn sample(&self, u: f64, v: f64, footprint: Footprint) -> f64 {
        match self {
            Texture::Flat { gray } => *gray,
            Texture::Markers { background, discs } => {
                let width = 0.5 * (footprint.du + footprint.dv);
                discs.iter().fold(*background, |g, d| {
                    let coverage = disc_coverage(u - d.u, v - d.v, d.radius, width);
                    g + coverage * (d.gray - g)
                })
            }
            Texture::Procedural(p) => p.sample(u, v, footprint),
        }
    }
}

impl ProceduralTexture {
    /// The gray level at `(u, v)` averaged over `footprint`.
    pub fn sample(&self, u: f64, v: f64, footprint: Footprint) -> f64 {
        let f = Footprint {
            du: footprint.du.max(1e-6),
            dv: footprint.dv.max(1e-6),
        };
        let widest = f.max();
        let inverse = Footprint {
            du: 1.0 / f.du,
            dv: 1.0 / f.dv,
        };
        let mut gray = self.base_gray
            + self.shading * fractal_noise(self.seed, u, v, self.shading_wavelength, widest);
        for (index, layer) in self.layers.iter().enumerate() {
            let cell = layer.cell_u.min(layer.cell_v);
            // Full detail while a cell spans ≥ 1/0.15 pixels, none below 2.
            let visibility = if widest <= 0.15 * cell {
                1.0
            } else {
                fade(widest / cell, 0.15, 0.5)
            };
            if visibility < 1.0 {
                // The layer's average, as a mip level would hold it.
                let (mean_gray, mean_coverage) = layer.mean();
                gray += (1.0 - visibility) * mean_coverage * (mean_gray - gray);
            }
            if visibility > 0.0 {
                if let Some((shape_gray, coverage)) =
                    self.shape_at(index as u64, layer, u, v, f, inverse)
                {
                    gray += visibility * coverage * (shape_gray - gray);
                }
            }
        }
        gray
    }

    /// True when the zone holding `(u, v)` is texture-poor.
    fn in_flat_zone(&self, u: f64, v: f64) -> bool {
        if self.flat_zone_fraction <= 0.0 {
            return false;
        }
        let inverse = 1.0 / self.flat_zone_size;
        let zx = floor(u * inverse) as i64;
        let zy = floor(v * inverse) as i64;
        unit_from_bits(hash_cell(self.seed, 1_000, zx, zy)) < self.flat_zone_fraction
    }

    /// The gray level and coverage of the shape of the cell holding `(u, v)`
    /// (`None` for an empty cell); `inverse` holds 1/`f`'s widths.
    fn shape_at(
        &self,
        index: u64,
        layer: &ShapeLayer,
        u: f64,
        v: f64,
        f: Footprint,
        inverse: Footprint,
    ) -> Option<(f64, f64)> {
        let cx = floor(u / layer.cell_u);
        let cy = floor(v / layer.cell_v);
        // Six 10-bit uniforms from one hash: occupancy, size, aspect,
        // centre u, centre v, gray.
        let bits = hash_cell(self.seed, index, cx as i64, cy as i64);
        let uniform = |k: u32| ((bits >> (10 * k)) & 1023) as f64 / 1024.0 + 1.0 / 2048.0;
        let within = |k: u32, low: f64, high: f64| low + (high - low) * uniform(k);
        if uniform(0) >= layer.occupancy {
            return None;
        }
        let (su, sv) = if layer.regular {
            (layer.size_max, layer.size_max)
        } else {
            let s = within(1, layer.size_min, layer.size_max);
            let aspect = within(2, 0.6, 1.0 / 0.6).sqrt();
            ((s * aspect).min(0.9), (s / aspect).min(0.9))
        };
        let (su, sv) = if layer.kind == ShapeKind::Disc {
            (su.min(sv), su.min(sv))
        } else {
            (su, sv)
        };
        let (ou, ov) = if layer.regular {
            (0.5, 0.5)
        } else {
            let margin_u = 0.05 + 0.5 * su;
            let margin_v = 0.05 + 0.5 * sv;
            (
                within(3, margin_u, 1.0 - margin_u),
                within(4, margin_v, 1.0 - margin_v),
            )
        };
        let centre_u = (cx + ou) * layer.cell_u;
        let centre_v = (cy + ov) * layer.cell_v;
        if layer.detail && self.in_flat_zone(centre_u, centre_v) {
            return None;
        }
        let gray = within(5, layer.gray_min, layer.gray_max);
        let half_u = 0.5 * su * layer.cell_u;
        let half_v = 0.5 * sv * layer.cell_v;
        let (x, y) = (u - centre_u, v - centre_v);
        let along_u = |low, high| box_overlap(x, low, high, f.du, inverse.du);
        let along_v = |low, high| box_overlap(y, low, high, f.dv, inverse.dv);
        match layer.kind {
            ShapeKind::Rectangle => {
                Some((gray, along_u(-half_u, half_u) * along_v(-half_v, half_v)))
            }
            ShapeKind::Disc => Some((gray, disc_coverage(x, y, half_u, 0.5 * (f.du + f.dv)))),
            ShapeKind::Checker => {
                let other = 255.0 - gray;
                let (u_neg, u_pos) = (along_u(-half_u, 0.0), along_u(0.0, half_u));
                let (v_neg, v_pos) = (along_v(-half_v, 0.0), along_v(0.0, half_v));
                let first = u_pos * v_pos + u_neg * v_neg;
                let second = u_pos * v_neg + u_neg * v_pos;
                let coverage = first + second;
                (coverage > 0.0).then(|| ((first * gray + second * other) / coverage, coverage))
            }
        }
    }
}

impl ShapeLayer {
    /// The layer's average gray level and coverage (what remains of it
    /// when its shapes are far smaller than a pixel).
    fn mean(&self) -> (f64, f64) {
        let size = if self.regular {
            self.size_max * self.size_max
        } else {
            let s = 0.5 * (self.size_min + self.size_max);
            s * s
        };
        let area = match self.kind {
            ShapeKind::Disc => size * std::f64::consts::FRAC_PI_4,
            ShapeKind::Rectangle | ShapeKind::Checker => size,
        };
        let gray = match self.kind {
            ShapeKind::Checker => 127.5,
            _ => 0.5 * (self.gray_min + self.gray_max),
        };
        (gray, self.occupancy * area)
    }
}

/// The share of the window `[x − w/2, x + w/2]` inside `[low, high]`
/// (`inverse_width` = 1/w).
fn box_overlap(x: f64, low: f64, high: f64, width: f64, inverse_width: f64) -> f64 {
    let overlap = (x + 0.5 * width).min(high) - (x - 0.5 * width).max(low);
    (overlap * inverse_width).max(0.0)
}

/// The share of a pixel of `width` metres at offset `(x, y)` from a disc's
/// centre that the disc covers (a linear ramp across the edge, scaled down
/// for discs smaller than the pixel).
fn disc_coverage(x: f64, y: f64, radius: f64, width: f64) -> f64 {
    let width = width.max(1e-6);
    let distance = (x * x + y * y).sqrt();
    let edge = ((radius - distance) / width + 0.5).clamp(0.0, 1.0);
    let diameter = 2.0 * radius;
    if diameter < width {
        edge * (diameter / width)
    } else {
        edge
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(kind: ShapeKind) -> ShapeLayer {
        ShapeLayer {
            cell_u: 1.0,
            cell_v: 1.0,
            occupancy: 1.0,
            kind,
            size_min: 0.3,
            size_max: 0.6,
            regular: false,
            gray_min: 20.0,
            gray_max: 230.0,
            detail: true,
        }
    }

    fn texture(kind: ShapeKind) -> ProceduralTexture {
        ProceduralTexture {
            seed: 5,
            base_gray: 128.0,
            shading: 10.0,
            shading_wavelength: 4.0,
            flat_zone_size: 4.0,
            flat_zone_fraction: 0.0,
            layers: vec![layer(kind)],
        }
    }

    #[test]
    fn box_overlap_is_the_exact_share() {
        assert_eq!(box_overlap(0.0, -1.0, 1.0, 0.5, 2.0), 1.0);
        assert_eq!(box_overlap(1.0, -1.0, 1.0, 0.5, 2.0), 0.5);
        assert_eq!(box_overlap(3.0, -1.0, 1.0, 0.5, 2.0), 0.0);
        // A window wider than the interval: the interval's share of it.
        assert!((box_overlap(0.0, -0.1, 0.1, 1.0, 1.0) - 0.2).abs() < 1e-12);
    }

    #[test]
    fn sampling_is_deterministic_and_seed_dependent() {
        let f = Footprint { du: 0.01, dv: 0.01 };
        let a = texture(ShapeKind::Rectangle);
        let mut b = a.clone();
        b.seed = 6;
        let mut differs = false;
        for i in 0..200 {
            let (u, v) = (i as f64 * 0.173, i as f64 * 0.071);
            assert_eq!(a.sample(u, v, f), a.sample(u, v, f));
            differs |= a.sample(u, v, f) != b.sample(u, v, f);
        }
        assert!(differs);
    }

    #[test]
    fn a_huge_footprint_averages_to_the_layer_mean() {
        // Cells far below a pixel: only the shading's coarse octave and the
        // layers' averages remain, so neighbouring samples barely differ.
        let t = texture(ShapeKind::Checker);
        let f = Footprint { du: 5.0, dv: 5.0 };
        let a = t.sample(10.0, 10.0, f);
        let b = t.sample(10.37, 10.61, f);
        assert!((a - b).abs() < 1.0, "{a} vs {b}");
    }

    #[test]
    fn flat_zones_drop_the_detail_layers() {
        let mut t = texture(ShapeKind::Disc);
        t.flat_zone_fraction = 1.0;
        t.shading = 0.0;
        let f = Footprint { du: 0.01, dv: 0.01 };
        for i in 0..100 {
            assert_eq!(t.sample(i as f64 * 0.31, i as f64 * 0.17, f), 128.0);
        }
    }

    #[test]
    fn markers_paint_discs_with_antialiased_edges() {
        let t = Texture::Markers {
            background: 50.0,
            discs: vec![DiscMarker {
                u: 1.0,
                v: 2.0,
                radius: 0.1,
                gray: 250.0,
            }],
        };
        let f = Footprint { du: 0.02, dv: 0.02 };
        assert_eq!(t.sample(1.0, 2.0, f), 250.0);
        assert_eq!(t.sample(1.5, 2.0, f), 50.0);
        assert!((t.sample(1.1, 2.0, f) - 150.0).abs() < 1e-9);
    }
}
