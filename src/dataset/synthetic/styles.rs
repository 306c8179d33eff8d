//! Texture presets: façades, asphalt, indoor walls, floor tiles, ceilings,
//! and for the open road grass verges, distant buildings and hillsides.
//! Sizes are in metres; each preset mixes corners (rectangles, checkers)
//! and blobs (discs) at several scales with texture-poor zones. The
//! distant presets are built for 10–40 cm pixels (surfaces 40–150 m away):
//! their coarsest shapes span tens of pixels, their finest a few.

use super::texture::{ProceduralTexture, ShapeKind, ShapeLayer, Texture};

/// A shape layer with random sizes and positions.
fn scatter(
    cell: f64,
    occupancy: f64,
    kind: ShapeKind,
    size: [f64; 2],
    gray: [f64; 2],
) -> ShapeLayer {
    ShapeLayer {
        cell_u: cell,
        cell_v: cell,
        occupancy,
        kind,
        size_min: size[0],
        size_max: size[1],
        regular: false,
        gray_min: gray[0],
        gray_max: gray[1],
        detail: true,
    }
}

/// A regular grid of centred rectangles (windows, doors, lamps, tiles).
fn grid(cell: [f64; 2], occupancy: f64, size: f64, gray: [f64; 2]) -> ShapeLayer {
    ShapeLayer {
        cell_u: cell[0],
        cell_v: cell[1],
        occupancy,
        kind: ShapeKind::Rectangle,
        size_min: size,
        size_max: size,
        regular: true,
        gray_min: gray[0],
        gray_max: gray[1],
        detail: false,
    }
}

/// A building façade: rows of windows, panels and posters, checkers,
/// discs and small marks; a quarter of 5-m zones are bare plaster.
pub fn facade(seed: u64) -> Texture {
    plaster(
        seed,
        0.25,
        vec![
            grid([3.0, 3.2], 0.85, 0.5, [25.0, 110.0]),
            scatter(2.3, 0.35, ShapeKind::Rectangle, [0.3, 0.8], [40.0, 220.0]),
            scatter(1.1, 0.25, ShapeKind::Checker, [0.25, 0.55], [10.0, 90.0]),
            scatter(0.7, 0.35, ShapeKind::Disc, [0.3, 0.7], [30.0, 230.0]),
            scatter(0.3, 0.45, ShapeKind::Rectangle, [0.3, 0.7], [50.0, 200.0]),
            scatter(0.1, 0.3, ShapeKind::Rectangle, [0.3, 0.7], [110.0, 190.0]),
        ],
    )
}

/// The plaster every varied or bare façade is painted on: gray 150 with
/// smooth 6-m shading, `flat_zone_fraction` of 5-m zones left without
/// detail, and `layers` on top.
fn plaster(seed: u64, flat_zone_fraction: f64, layers: Vec<ShapeLayer>) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 150.0,
        shading: 22.0,
        shading_wavelength: 6.0,
        flat_zone_size: 5.0,
        flat_zone_fraction,
        layers,
    })
}

/// How a scene's façades look; a hard condition can change them
/// (see [`super::conditions::Condition::facades`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Facades {
    /// Each façade its own mix of windows, panels and marks ([`facade`]).
    #[default]
    Varied,
    /// Mostly bare plaster: low texture ([`bare_facade`]).
    Bare,
    /// One periodic pattern on every façade: repeated texture
    /// ([`repeated_facade`]).
    Repeated,
}

impl Facades {
    /// The texture of the façade with `seed`.
    pub fn texture(self, seed: u64) -> Texture {
        match self {
            Facades::Varied => facade(seed),
            Facades::Bare => bare_facade(seed),
            Facades::Repeated => repeated_facade(),
        }
    }
}

/// A low-texture façade: smooth shading over bare plaster, three quarters
/// of 5-m zones without any detail, sparse windows and a few panels.
pub fn bare_facade(seed: u64) -> Texture {
    plaster(
        seed,
        0.75,
        vec![
            grid([3.0, 3.2], 0.3, 0.5, [60.0, 110.0]),
            scatter(2.3, 0.15, ShapeKind::Rectangle, [0.3, 0.8], [90.0, 200.0]),
        ],
    )
}

/// A repeated-texture façade, the same on every wall (the seed is not
/// used): a regular grid of identical framed windows and small marks,
/// periodic with 3 m × 3.2 m, and nothing else: every window looks like
/// every other.
pub fn repeated_facade() -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed: 0,
        base_gray: 150.0,
        shading: 0.0,
        shading_wavelength: 6.0,
        flat_zone_size: 5.0,
        flat_zone_fraction: 0.0,
        layers: vec![
            grid([3.0, 3.2], 1.0, 0.6, [200.0, 200.0]),
            grid([3.0, 3.2], 1.0, 0.4, [50.0, 50.0]),
            grid([1.0, 1.6], 1.0, 0.2, [90.0, 90.0]),
        ],
    })
}

/// Asphalt: repair patches, stains and manholes, gravel speckle; a third
/// of 6-m zones are fresh, even tarmac.
pub fn asphalt(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 95.0,
        shading: 12.0,
        shading_wavelength: 8.0,
        flat_zone_size: 6.0,
        flat_zone_fraction: 0.3,
        layers: vec![
            scatter(3.0, 0.3, ShapeKind::Rectangle, [0.3, 0.8], [65.0, 135.0]),
            scatter(1.3, 0.25, ShapeKind::Disc, [0.3, 0.7], [40.0, 170.0]),
            scatter(0.6, 0.2, ShapeKind::Checker, [0.2, 0.5], [40.0, 80.0]),
            scatter(0.35, 0.4, ShapeKind::Rectangle, [0.3, 0.7], [60.0, 150.0]),
            scatter(0.08, 0.5, ShapeKind::Rectangle, [0.3, 0.7], [55.0, 165.0]),
        ],
    })
}

/// An indoor wall: doors, posters, notices, switches; a third of 2-m
/// zones are bare paint.
pub fn indoor_wall(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 175.0,
        shading: 15.0,
        shading_wavelength: 3.0,
        flat_zone_size: 2.0,
        flat_zone_fraction: 0.3,
        layers: vec![
            scatter(1.6, 0.5, ShapeKind::Rectangle, [0.4, 0.85], [40.0, 230.0]),
            scatter(0.7, 0.3, ShapeKind::Checker, [0.25, 0.6], [10.0, 90.0]),
            scatter(0.45, 0.4, ShapeKind::Disc, [0.3, 0.7], [30.0, 230.0]),
            scatter(0.2, 0.45, ShapeKind::Rectangle, [0.3, 0.7], [50.0, 210.0]),
            scatter(0.06, 0.3, ShapeKind::Rectangle, [0.3, 0.7], [120.0, 210.0]),
        ],
    })
}

/// Floor tiles of slightly different grays with dark joints, plus marks.
pub fn floor_tiles(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 70.0,
        shading: 8.0,
        shading_wavelength: 4.0,
        flat_zone_size: 3.0,
        flat_zone_fraction: 0.3,
        layers: vec![
            grid([0.6, 0.6], 1.0, 0.9, [110.0, 160.0]),
            scatter(0.9, 0.25, ShapeKind::Disc, [0.2, 0.6], [40.0, 210.0]),
            scatter(0.25, 0.3, ShapeKind::Rectangle, [0.3, 0.7], [60.0, 200.0]),
        ],
    })
}

/// A ceiling: bright lamp panels in a grid over plain, slightly marked board.
pub fn ceiling(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 200.0,
        shading: 10.0,
        shading_wavelength: 4.0,
        flat_zone_size: 3.0,
        flat_zone_fraction: 0.5,
        layers: vec![
            grid([2.4, 2.4], 0.8, 0.35, [235.0, 255.0]),
            scatter(0.8, 0.3, ShapeKind::Rectangle, [0.2, 0.6], [120.0, 190.0]),
            scatter(0.3, 0.3, ShapeKind::Disc, [0.3, 0.7], [100.0, 180.0]),
        ],
    })
}

/// A grass verge: bushes and dark patches, lighter gravel strips, stones
/// and litter; a third of 8-m zones are plain grass.
pub fn verge(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 135.0,
        shading: 18.0,
        shading_wavelength: 12.0,
        flat_zone_size: 8.0,
        flat_zone_fraction: 0.3,
        layers: vec![
            scatter(4.0, 0.3, ShapeKind::Disc, [0.4, 0.85], [45.0, 95.0]),
            scatter(2.2, 0.3, ShapeKind::Rectangle, [0.3, 0.8], [130.0, 185.0]),
            scatter(0.9, 0.3, ShapeKind::Disc, [0.3, 0.7], [40.0, 200.0]),
            scatter(0.4, 0.35, ShapeKind::Checker, [0.3, 0.6], [30.0, 100.0]),
            scatter(0.12, 0.4, ShapeKind::Rectangle, [0.3, 0.7], [90.0, 160.0]),
        ],
    })
}

/// Buildings seen from 40–150 m (warehouses, offices, blocks): storey-high
/// panels and bays, a grid of 2-m windows, signs and marks down to 0.4 m,
/// so that the texture has corners at every scale from a few pixels to
/// tens; a sixth of 16-m zones are bare cladding.
pub fn distant_buildings(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 150.0,
        shading: 28.0,
        shading_wavelength: 30.0,
        flat_zone_size: 16.0,
        flat_zone_fraction: 0.15,
        layers: vec![
            scatter(
                14.0,
                0.55,
                ShapeKind::Rectangle,
                [0.45, 0.85],
                [50.0, 215.0],
            ),
            grid([4.0, 3.6], 0.8, 0.5, [20.0, 105.0]),
            scatter(7.0, 0.35, ShapeKind::Checker, [0.35, 0.7], [10.0, 90.0]),
            scatter(3.2, 0.35, ShapeKind::Disc, [0.35, 0.75], [25.0, 235.0]),
            scatter(1.6, 0.4, ShapeKind::Rectangle, [0.3, 0.75], [40.0, 220.0]),
            scatter(0.7, 0.35, ShapeKind::Rectangle, [0.3, 0.7], [80.0, 210.0]),
        ],
    })
}

/// A wooded hillside seen from 50–300 m: fields and rock faces, clumps of
/// trees at three scales, boulders and clearings; a tenth of 25-m zones
/// are plain meadow.
pub fn hillside(seed: u64) -> Texture {
    Texture::Procedural(ProceduralTexture {
        seed,
        base_gray: 120.0,
        shading: 30.0,
        shading_wavelength: 45.0,
        flat_zone_size: 25.0,
        flat_zone_fraction: 0.1,
        layers: vec![
            scatter(18.0, 0.5, ShapeKind::Rectangle, [0.5, 0.9], [70.0, 185.0]),
            scatter(9.0, 0.55, ShapeKind::Disc, [0.5, 0.9], [25.0, 90.0]),
            scatter(4.5, 0.45, ShapeKind::Disc, [0.4, 0.85], [35.0, 170.0]),
            scatter(3.0, 0.3, ShapeKind::Checker, [0.35, 0.65], [20.0, 95.0]),
            scatter(1.8, 0.45, ShapeKind::Disc, [0.3, 0.8], [20.0, 210.0]),
            scatter(0.8, 0.4, ShapeKind::Rectangle, [0.3, 0.7], [60.0, 200.0]),
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::synthetic::texture::Footprint;

    const FINE: Footprint = Footprint { du: 0.01, dv: 0.01 };

    /// Share of sample points (every 5 cm over 30 m × 15 m) whose gray
    /// differs by more than 10 levels from the point 5 cm to the right.
    fn edge_share(texture: &Texture) -> f64 {
        let (mut edges, mut total) = (0usize, 0usize);
        for i in 0..600 {
            for j in 0..300 {
                let (u, v) = (i as f64 * 0.05, j as f64 * 0.05);
                let step = texture.sample(u + 0.05, v, FINE) - texture.sample(u, v, FINE);
                edges += usize::from(step.abs() > 10.0);
                total += 1;
            }
        }
        edges as f64 / total as f64
    }

    #[test]
    fn the_repeated_facade_is_the_same_on_every_wall_and_periodic() {
        let (a, b) = (repeated_facade(), Facades::Repeated.texture(12345));
        let mut grays = Vec::new();
        for i in 0..97 {
            let (u, v) = (0.137 * i as f64, 0.291 * i as f64);
            let g = a.sample(u, v, FINE);
            assert_eq!(g, b.sample(u, v, FINE), "the seed changes nothing");
            for (du, dv) in [(3.0, 0.0), (0.0, 3.2), (6.0, 6.4)] {
                let shifted = a.sample(u + du, v + dv, FINE);
                assert!((g - shifted).abs() < 1e-9, "({u}, {v}) + ({du}, {dv})");
            }
            grays.push(g);
        }
        let distinct = grays
            .iter()
            .filter(|&&g| (g - grays[0]).abs() > 20.0)
            .count();
        assert!(distinct > 10, "the pattern has contrast: {grays:?}");
    }

    #[test]
    fn the_bare_facade_has_far_fewer_edges_than_the_varied_one() {
        for seed in [1, 2, 3] {
            let (varied, bare) = (edge_share(&facade(seed)), edge_share(&bare_facade(seed)));
            eprintln!("seed {seed}: edge share varied {varied:.4}, bare {bare:.4}");
            assert!(bare > 0.0, "seed {seed}: some texture is left");
            assert!(
                bare < 0.4 * varied,
                "seed {seed}: bare {bare}, varied {varied}"
            );
        }
        assert_eq!(Facades::Varied.texture(7), facade(7));
        assert_eq!(Facades::Bare.texture(7), bare_facade(7));
    }
}
