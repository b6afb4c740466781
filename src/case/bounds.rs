//! The admissible and the usual range of every numeric case key, in one
//! table ([`BOUNDS`]): the checker refuses a value outside the hard range
//! at parse time (file, line, key, value, range) and warns about a value
//! outside the usual range ([`CaseWarning`](crate::config::CaseWarning)),
//! so that research inputs still run. `docs/cases.md`, "Ranges", states
//! every row with the same numbers; a test compares them.
//!
//! **Hard ranges** are set where a value is impossible or overflows the
//! computation: lengths beyond a kilometre (10⁶ mm; tessellations, drawn
//! points and contact searches square them), a Coulomb coefficient beyond
//! 10 (no dry contact reaches it; the friction force `μ p` of 10³⁰⁸
//! overflows), masses and stiffnesses whose products with ordinary strains
//! or accelerations overflow. **Usual ranges** are physical: what dry
//! fabrics and forming benches measure.

use toml::Spanned;

use crate::config::{ConfigError, TomlChecker, readable_number};

/// An interval of the real line, each end open or closed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// `true` when `lo` itself is excluded.
    pub lo_open: bool,
    /// Upper end.
    pub hi: f64,
    /// `true` when `hi` itself is excluded.
    pub hi_open: bool,
}

impl Interval {
    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Self {
        Self {
            lo,
            lo_open: false,
            hi,
            hi_open: false,
        }
    }

    /// `(lo, hi]`.
    pub const fn left_open(lo: f64, hi: f64) -> Self {
        Self {
            lo,
            lo_open: true,
            hi,
            hi_open: false,
        }
    }

    /// `(lo, hi)`.
    pub const fn open(lo: f64, hi: f64) -> Self {
        Self {
            lo,
            lo_open: true,
            hi,
            hi_open: true,
        }
    }

    /// `[lo, hi)`.
    pub const fn right_open(lo: f64, hi: f64) -> Self {
        Self {
            lo,
            lo_open: false,
            hi,
            hi_open: true,
        }
    }

    /// `true` when `x` is finite and inside.
    pub fn contains(&self, x: f64) -> bool {
        x.is_finite()
            && (if self.lo_open {
                x > self.lo
            } else {
                x >= self.lo
            })
            && (if self.hi_open {
                x < self.hi
            } else {
                x <= self.hi
            })
    }
}

impl std::fmt::Display for Interval {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}{}, {}{}",
            if self.lo_open { '(' } else { '[' },
            compact(self.lo),
            compact(self.hi),
            if self.hi_open { ')' } else { ']' }
        )
    }
}

/// A range's end as a reader wants it: plain between 10⁻³ and 10⁴
/// (`0.05`, `1000`), in exponent form outside (`1e6`, `1e-4`).
fn compact(x: f64) -> String {
    if x == 0.0 || (1e-3..1e4).contains(&x.abs()) {
        readable_number(x)
    } else {
        format!("{x:e}")
    }
}

/// The ranges of one key (or of keys that mean the same quantity, such as
/// `material.areal_mass` and `ply.areal_mass`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// The keys as `docs/cases.md` names them (`table.key`).
    pub keys: &'static [&'static str],
    /// What an error expects, before the range: `a length > 0 mm`.
    pub rule: &'static str,
    /// The unit (`mm`, `kg/m²`; `—` for a pure number).
    pub unit: &'static str,
    /// Values outside are refused.
    pub hard: Interval,
    /// Values inside `hard` but outside this give a warning; `None`: no
    /// usual range. A value of exactly 0 where 0 is admissible switches
    /// the quantity off and is never unusual.
    pub usual: Option<Interval>,
    /// The warning's hint at what was probably meant.
    pub hint: &'static str,
    /// Why the ranges are what they are (the docs' "why" column).
    pub why: &'static str,
}

/// Largest `explicit.roving_mass_length` \[mm\]: a coupling mass reaching
/// over a metre of roving, far past any bench's size (`docs/explicit.md`,
/// "Roving mass scaling").
pub const MAX_ROVING_MASS_LENGTH: f64 = 1000.0;

/// Largest length, position or displacement of a case \[mm\]: a kilometre.
pub const MAX_LENGTH: f64 = 1.0e6;

const LENGTH: Interval = Interval::left_open(0.0, MAX_LENGTH);
const LENGTH_OR_ZERO: Interval = Interval::closed(0.0, MAX_LENGTH);
const POSITION: Interval = Interval::closed(-MAX_LENGTH, MAX_LENGTH);
const KM: &str = "a kilometre: beyond any specimen, blank or press; keeps the squares of lengths in meshing, drawing and contact searches far from overflow";

/// Every bounded numeric key of the OAT and forming case files (the forming
/// `[output]` counts are checked by their own table's code).
pub const BOUNDS: &[Bound] = &[
    // --- OAT [specimen], [mesh], [output] ---
    Bound {
        keys: &["specimen.width", "specimen.length"],
        rule: "a length > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: Some(Interval::closed(10.0, 2000.0)),
        hint: "off-axis tension specimens are tens to hundreds of mm (the paper: 100 × 300 mm); mm, not m?",
        why: "a kilometre, beyond any specimen; usual: the specimens of off-axis tension tests",
    },
    Bound {
        keys: &["specimen.bias_angle_deg"],
        rule: "an angle in [-90, 90] degrees",
        unit: "deg",
        hard: Interval::closed(-90.0, 90.0),
        usual: None,
        hint: "",
        why: "every direction of the rovings is one of these; a negative angle is the mirror image",
    },
    Bound {
        keys: &[
            "mesh.element_size",
            "output.mdz_size",
            "ply.mesh.element_size",
        ],
        rule: "a length > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["mesh.nx", "mesh.ny"],
        rule: "a count in 1..=100000",
        unit: "—",
        hard: Interval::closed(1.0, 100_000.0),
        usual: None,
        hint: "",
        why: "10⁵ cells along a side; the triangle count is limited separately (5,000,000)",
    },
    Bound {
        keys: &["ply.mesh.cells"],
        rule: "two counts in 1..=100000 [nx, ny]",
        unit: "—",
        hard: Interval::closed(1.0, 100_000.0),
        usual: None,
        hint: "",
        why: "as `mesh.nx`, `mesh.ny`",
    },
    // --- plies and OAT [material] ---
    Bound {
        keys: &["material.thickness"],
        rule: "a length > 0 mm",
        unit: "mm",
        hard: Interval::left_open(0.0, 1000.0),
        usual: Some(Interval::closed(0.05, 5.0)),
        hint: "a dry UD-NCF ply is 0.1–1 mm thick (the paper: 0.3 mm)",
        why: "a metre-thick membrane is no fabric; usual: single plies of dry fabrics",
    },
    // --- forming [rosette], [defects] ---
    Bound {
        keys: &["rosette.origin"],
        rule: "a position in mm",
        unit: "mm",
        hard: POSITION,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &[
            "defects.tool_gap",
            "defects.waviness_wavelength",
            "defects.roving_pitch",
            "defects.gap_width",
        ],
        rule: "a length > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: Some(Interval::closed(0.01, 100.0)),
        hint: "gaps, pitches and wavelengths of a formed ply are tenths of a mm to tens of mm; mm, not m?",
        why: "a kilometre, beyond any part; usual: the scales of plies, rovings and wrinkles",
    },
    Bound {
        keys: &["defects.curvature"],
        rule: "a curvature > 0 1/mm",
        unit: "1/mm",
        hard: Interval::left_open(0.0, 1000.0),
        usual: Some(Interval::closed(0.001, 10.0)),
        hint: "the inverse of a radius in mm: 0.05 is a 20 mm radius",
        why: "a micrometre radius, below any mesh; usual: radii from 0.1 mm to 1 m",
    },
    Bound {
        keys: &["defects.slack_line_force", "defects.waviness_line_force"],
        rule: "a line force > 0 N/mm",
        unit: "N/mm",
        hard: Interval::left_open(0.0, 1.0e6),
        usual: Some(Interval::closed(1.0e-6, 100.0)),
        hint: "membrane forces of a dry ply are small: its own weight makes about 1e-4 N/mm",
        why: "a meganewton per mm, beyond any press; usual: a dry ply's membrane forces",
    },
    Bound {
        keys: &["ply.thickness"],
        rule: "a thickness > 0 mm",
        unit: "mm",
        hard: Interval::left_open(0.0, 1000.0),
        usual: Some(Interval::closed(0.05, 5.0)),
        hint: "a dry UD-NCF ply is 0.1–1 mm thick (the paper: 0.3 mm)",
        why: "a metre-thick membrane is no fabric; usual: single plies of dry fabrics",
    },
    Bound {
        keys: &["material.areal_mass", "ply.areal_mass"],
        rule: "an areal mass > 0 kg/m²",
        unit: "kg/m²",
        hard: Interval::closed(1.0e-4, 1000.0),
        usual: Some(Interval::closed(0.05, 5.0)),
        hint: "fabrics weigh 0.05–5 kg/m² (the paper's: 0.30); a value in g/m² is 1000 times too large",
        why: "0.1 g/m² is lighter than any veil, a tonne per m² heavier than a 10 cm steel plate; beyond them the explicit step and the contact penalty (both ∝ mass) over- or underflow (1e-308 gave a denormal density); usual: dry fabrics",
    },
    Bound {
        keys: &["material.density"],
        rule: "a density > 0 t/mm³ (1.0e-9 for 0.30 kg/m² at 0.3 mm)",
        unit: "t/mm³",
        hard: Interval::closed(1.0e-15, 1.0e-6),
        usual: Some(Interval::closed(1.0e-10, 3.0e-9)),
        hint: "dry fabrics: 0.1–3 g/cm³ = 1e-10–3e-9 t/mm³ (the paper's: 1e-9); a value in kg/m³ or g/cm³ is in the wrong unit",
        why: "1e-15 t/mm³ is a thousandth of air's density, 1e-6 forty times osmium's; usual: dry fabrics",
    },
    Bound {
        keys: &["ply.fibre_angle_deg"],
        rule: "an angle in [-360, 360] degrees",
        unit: "deg",
        hard: Interval::closed(-360.0, 360.0),
        usual: None,
        hint: "",
        why: "one turn either way",
    },
    Bound {
        keys: &["ply.bending.b11", "ply.bending.b22", "ply.bending.b66"],
        rule: "a bending stiffness ≥ 0 N·mm",
        unit: "N·mm",
        hard: Interval::closed(0.0, 1.0e9),
        usual: Some(Interval::closed(1.0e-3, 100.0)),
        hint: "dry fabrics: 1e-3–100 N·mm (the paper: B11 = 4.06, B22 = 0.018)",
        why: "1e9 N·mm is the plate stiffness of 40 mm of steel; B κ² of 1e308 overflows at any curvature; usual: dry fabrics",
    },
    Bound {
        keys: &["ply.compaction.pressure"],
        rule: "a pressure scale > 0 MPa",
        unit: "MPa",
        hard: Interval::left_open(0.0, 1.0e4),
        usual: Some(Interval::closed(1.0e-5, 0.1)),
        hint: "dry fabrics: 1e-4–1e-2 MPa (docs/theory.md, \"Compaction of the fabric layer\")",
        why: "10 GPa is the stiffness of the fibres themselves, no packing; usual: the packing laws of dry reinforcements",
    },
    Bound {
        keys: &["ply.compaction.exponent"],
        rule: "a packing exponent > 1",
        unit: "",
        hard: Interval::left_open(1.0, 100.0),
        usual: Some(Interval::closed(3.0, 20.0)),
        hint: "dry fabrics: 5–15 (Toll's planar network: 5; aligned rovings: higher)",
        why: "n ≤ 1 stores no finite energy in the layer's law (Eq. C4); above 100 the layer is rigid at once; usual: dry reinforcements",
    },
    // --- [ply.mesh] generators, [[zone]] ---
    Bound {
        keys: &["ply.mesh.size"],
        rule: "two lengths > 0 mm [x, y]",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["zone.size"],
        rule: "two sizes > 0 mm [x, y]",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["ply.mesh.radius"],
        rule: "a radius > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["ply.mesh.width"],
        rule: "a width > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["ply.mesh.tail_length"],
        rule: "a length ≥ 0 mm",
        unit: "mm",
        hard: LENGTH_OR_ZERO,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["ply.mesh.wrap_angle_deg"],
        rule: "an angle in (0, 360) degrees",
        unit: "deg",
        hard: Interval::open(0.0, 360.0),
        usual: None,
        hint: "",
        why: "a strip wrapped a full turn or more would overlap itself",
    },
    Bound {
        keys: &[
            "ply.mesh.centre",
            "zone.centre",
            "tool.origin",
            "tool.section_at",
            "boundary.displacement",
        ],
        rule: "finite coordinates [mm]",
        unit: "mm",
        hard: POSITION,
        usual: None,
        hint: "",
        why: KM,
    },
    // --- [[tool]] ---
    Bound {
        keys: &[
            "tool.radius",
            "tool.major_radius",
            "tool.minor_radius",
            "tool.opening_radius",
            "tool.fillet_radius",
        ],
        rule: "a radius > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["tool.rounding_radius"],
        rule: "the radius of the apex and the edges > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["tool.height"],
        rule: "the pyramid's height from the apex to the base > 0 mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["tool.extent"],
        rule: "a half-size in (0, 1e6] mm",
        unit: "mm",
        hard: LENGTH,
        usual: None,
        hint: "",
        why: "drawn only: a kilometre is far beyond any press and keeps the drawn points finite",
    },
    Bound {
        keys: &["tool.clearance"],
        rule: "a clearance ≥ 0 mm between the punch and the opening",
        unit: "mm",
        hard: LENGTH_OR_ZERO,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["tool.displacement"],
        rule: "a finite displacement [mm]",
        unit: "mm",
        hard: POSITION,
        usual: None,
        hint: "",
        why: KM,
    },
    Bound {
        keys: &["tool.sides"],
        rule: "a count in 3..=64",
        unit: "—",
        hard: Interval::closed(3.0, 64.0),
        usual: None,
        hint: "",
        why: "a pyramid has at least three faces; beyond 64 it is a cone to drawing accuracy",
    },
    Bound {
        keys: &["tool.face_angle_deg"],
        rule: "an angle in (0, 90) degrees between the faces and the base plane",
        unit: "deg",
        hard: Interval::open(0.0, 90.0),
        usual: None,
        hint: "",
        why: "faces between the base plane and the axis",
    },
    Bound {
        keys: &["tool.scale"],
        rule: "a factor > 0 to mm",
        unit: "—",
        hard: Interval::left_open(0.0, 1.0e6),
        usual: Some(Interval::closed(1.0e-3, 1.0e4)),
        hint: "1 for mm, 1000 for metres, 25.4 for inches",
        why: "a file in mm drawn a kilometre per unit; usual: the length units of CAD files",
    },
    Bound {
        keys: &["tool.friction", "ply_contact.friction"],
        rule: "a Coulomb coefficient ≥ 0",
        unit: "—",
        hard: Interval::closed(0.0, 10.0),
        usual: Some(Interval::closed(0.05, 1.0)),
        hint: "dry fabrics on steel 0.1–0.5, on fabric 0.2–0.6 (the paper: 0.147 tool–ply, 0.336 ply–ply); 1.47 for 0.147?",
        why: "no dry contact reaches 10 (rubber on glass about 4); μ p of 1e308 overflows; usual: dry fabrics on steel and on fabric",
    },
    Bound {
        keys: &["tool.mass"],
        rule: "a mass > 0 kg",
        unit: "kg",
        hard: Interval::left_open(0.0, 1.0e6),
        usual: Some(Interval::closed(0.01, 1000.0)),
        hint: "blankholders of forming benches weigh about 1–100 kg; kg, not g?",
        why: "a thousand tonnes is beyond any press's moving mass, and mass × g of 1e308 overflows; usual: blankholders and punches",
    },
    Bound {
        keys: &["tool.weight"],
        rule: "a dead force ≥ 0 N along the tool's direction",
        unit: "N",
        hard: Interval::closed(0.0, 1.0e10),
        usual: None,
        hint: "",
        why: "the weight of a million tonnes; a force of 1e308 overflows the residual",
    },
    // --- conditions ---
    Bound {
        keys: &["load.force"],
        rule: "a finite force [N]",
        unit: "N",
        hard: Interval::closed(-1.0e10, 1.0e10),
        usual: None,
        hint: "",
        why: "the weight of a million tonnes; a force of 1e308 overflows the residual",
    },
    Bound {
        keys: &["gravity.g"],
        rule: "an acceleration ≥ 0 mm/s² (9810 on Earth)",
        unit: "mm/s²",
        hard: Interval::closed(0.0, 1.0e8),
        usual: Some(Interval::closed(9000.0, 10000.0)),
        hint: "9810 mm/s² on Earth: the unit is mm/s², not m/s²",
        why: "ten thousand g; usual: the Earth's (9780–9832 mm/s²)",
    },
    // --- contact ---
    Bound {
        keys: &["ply_contact.skin"],
        rule: "a distance in (0, 1000] mm",
        unit: "mm",
        hard: Interval::left_open(0.0, 1000.0),
        usual: None,
        hint: "",
        why: "a skin of a metre puts every triangle of a ply in every candidate list",
    },
    Bound {
        keys: &["contact.offset"],
        rule: "a distance ≥ 0 mm",
        unit: "mm",
        hard: Interval::closed(0.0, 1000.0),
        usual: Some(Interval::closed(0.01, 5.0)),
        hint: "half a ply's thickness (0.15 mm for the paper's 0.3 mm)",
        why: "a contact layer a metre thick is no contact; usual: half the ply thicknesses",
    },
    Bound {
        keys: &["contact.penalty"],
        rule: "a stiffness > 0 N/mm",
        unit: "N/mm",
        hard: Interval::left_open(0.0, 1.0e12),
        usual: None,
        hint: "",
        why: "a penalty times a penetration of a millimetre stays finite and the tangent keeps its digits",
    },
    Bound {
        keys: &["contact.penalty_scale"],
        rule: "a factor > 0",
        unit: "—",
        hard: Interval::left_open(0.0, 1.0e6),
        usual: None,
        hint: "",
        why: "a million times the automatic penalty leaves the tangent without digits",
    },
    Bound {
        keys: &["contact.tangential_penalty_scale"],
        rule: "a ratio > 0 of the tangential to the normal penalty",
        unit: "—",
        hard: Interval::left_open(0.0, 1.0e6),
        usual: None,
        hint: "",
        why: "as `contact.penalty_scale`",
    },
    Bound {
        keys: &["contact.normal_smoothing"],
        rule: "a gap width ≥ 0 mm",
        unit: "mm",
        hard: Interval::closed(0.0, 1000.0),
        usual: None,
        hint: "",
        why: "a metre: beyond any ply's thickness by three orders",
    },
    Bound {
        keys: &["contact.gap_tolerance"],
        rule: "a distance > 0 mm",
        unit: "mm",
        hard: Interval::left_open(0.0, 1000.0),
        usual: None,
        hint: "",
        why: "a metre: beyond any ply's thickness by three orders",
    },
    Bound {
        keys: &["contact.friction_smoothing"],
        rule: "a fraction in [0, 1) of the friction limit",
        unit: "—",
        hard: Interval::right_open(0.0, 1.0),
        usual: None,
        hint: "",
        why: "sliding starts at (1 − δ_r) μ t_N, which must stay > 0",
    },
    Bound {
        keys: &["contact.multiplier_tolerance"],
        rule: "a fraction > 0",
        unit: "—",
        hard: Interval::left_open(0.0, 1.0),
        usual: None,
        hint: "",
        why: "a relative change of more than 1 accepts any multipliers",
    },
    Bound {
        keys: &["contact.explicit_stiffness"],
        rule: "a fraction in (0, 1] of the stability limit",
        unit: "—",
        hard: Interval::left_open(0.0, 1.0),
        usual: None,
        hint: "",
        why: "of each node's central-difference limit 4m/Δt²: above it the run is unstable",
    },
    Bound {
        keys: &["contact.explicit_damping"],
        rule: "a fraction in [0, 1] of the critical damping",
        unit: "—",
        hard: Interval::closed(0.0, 1.0),
        usual: None,
        hint: "",
        why: "beyond critical damping the contact sticks",
    },
    Bound {
        keys: &["contact.explicit_pressure_stiffness"],
        rule: "a stiffness per unit area in (0, 1e12] N/mm³ (MPa per mm of penetration)",
        unit: "N/mm³",
        hard: Interval::left_open(0.0, 1.0e12),
        usual: None,
        hint: "",
        why: "the penalty per node stays finite for any cell up to a square kilometre",
    },
    // --- [explicit] ---
    Bound {
        keys: &["explicit.time_step", "explicit.mass_scaling_time_step"],
        rule: "a time step > 0 s",
        unit: "s",
        hard: Interval::left_open(0.0, 1.0),
        usual: Some(Interval::closed(1.0e-9, 1.0e-3)),
        hint: "stable steps of fabric meshes are about 1e-8–1e-5 s",
        why: "a step of a second is longer than any run; the mass scaling's (Δt_target/Δt)² of 1e308 overflows; usual: the stable steps of fabric meshes, mass-scaled",
    },
    Bound {
        keys: &["explicit.damping"],
        rule: "a coefficient ≥ 0 1/s",
        unit: "1/s",
        hard: Interval::closed(0.0, 1.0e9),
        usual: None,
        hint: "",
        why: "α Δt ≥ 1 at any step above a nanosecond: every node stopped at every step",
    },
    Bound {
        keys: &["explicit.roving_mass_length"],
        rule: "a length in [0, 1000] mm",
        unit: "mm",
        hard: Interval::closed(0.0, MAX_ROVING_MASS_LENGTH),
        usual: None,
        hint: "",
        why: "a coupling mass reaching over a metre of roving, far past any bench",
    },
    Bound {
        keys: &["explicit.duration"],
        rule: "a duration > 0 s",
        unit: "s",
        hard: Interval::left_open(0.0, 1.0e9),
        usual: None,
        hint: "",
        why: "thirty years; the speed stroke/duration must also be finite",
    },
    // --- [solver] ---
    Bound {
        keys: &["solver.max_wall_seconds", "solver.inertia_duration"],
        rule: "a number > 0",
        unit: "s",
        hard: Interval::left_open(0.0, 1.0e9),
        usual: None,
        hint: "",
        why: "thirty years",
    },
    Bound {
        keys: &["solver.residual_tolerance", "solver.energy_tolerance"],
        rule: "a number > 0",
        unit: "—",
        hard: Interval::open(0.0, 1.0),
        usual: None,
        hint: "",
        why: "a relative tolerance of 1 accepts the first guess",
    },
    Bound {
        keys: &[
            "solver.initial_increment",
            "solver.max_increment",
            "solver.min_increment",
        ],
        rule: "a number > 0",
        unit: "mm (OAT), — (forming)",
        hard: Interval::left_open(0.0, MAX_LENGTH),
        usual: None,
        hint: "",
        why: "a kilometre of clamp travel",
    },
    Bound {
        keys: &["solver.growth"],
        rule: "a factor ≥ 1",
        unit: "—",
        hard: Interval::closed(1.0, 100.0),
        usual: None,
        hint: "",
        why: "a hundredfold step after an easy one leaves no step to cut back to",
    },
];

/// The bound of `key` (`table.key` without indices: `tool.friction`).
///
/// # Panics
/// When `key` is not in [`BOUNDS`]: a programming error, caught by the
/// tests of every table.
pub fn bound(key: &str) -> &'static Bound {
    BOUNDS
        .iter()
        .find(|b| b.keys.contains(&key))
        .unwrap_or_else(|| panic!("no bound for {key}"))
}

impl Bound {
    /// `x` if it is inside the hard range (with a warning on `check` when
    /// it is outside the usual one), else an error naming `key` (the
    /// indexed key, `tool[1].friction`), `line`, the value and the range.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn check(
        &self,
        check: &TomlChecker,
        x: f64,
        line: usize,
        key: &str,
    ) -> Result<f64, ConfigError> {
        if !self.hard.contains(x) {
            return Err(check.invalid(line, key, readable_number(x), &self.expected()));
        }
        self.warn_unusual(check, x, line, key);
        Ok(x)
    }

    /// As [`Bound::check`] for a spanned value.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn spanned(
        &self,
        check: &TomlChecker,
        v: &Spanned<f64>,
        key: &str,
    ) -> Result<f64, ConfigError> {
        self.check(check, *v.get_ref(), check.line_of(v), key)
    }

    /// As [`Bound::check`] for an integer key, as a count.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn count(
        &self,
        check: &TomlChecker,
        v: &Spanned<i64>,
        key: &str,
    ) -> Result<usize, ConfigError> {
        let n = *v.get_ref();
        if self.hard.contains(n as f64) {
            Ok(n as usize)
        } else {
            Err(check.invalid(check.line_of(v), key, n.to_string(), &self.expected()))
        }
    }

    /// The warning of a value outside the usual range (0, where it is
    /// admissible, switches the quantity off and is not unusual).
    pub fn warn_unusual(&self, check: &TomlChecker, x: f64, line: usize, key: &str) {
        if let Some(usual) = &self.usual
            && !usual.contains(x)
            && !(x == 0.0 && self.hard.contains(0.0))
        {
            check.warn(
                line,
                key,
                readable_number(x),
                self.with_unit(usual),
                self.hint,
            );
        }
    }

    /// What the error message expects: the rule, then the admissible
    /// range unless the rule states it already (`a length > 0 mm;
    /// admissible: (0, 1e6] mm`).
    pub fn expected(&self) -> String {
        let hi = self.hard.hi;
        if self.rule.contains(&compact(hi)) || self.rule.contains(&readable_number(hi)) {
            self.rule.to_string()
        } else {
            format!("{}; admissible: {}", self.rule, self.with_unit(&self.hard))
        }
    }

    fn with_unit(&self, range: &Interval) -> String {
        if self.unit == "—" {
            range.to_string()
        } else {
            format!("{range} {}", self.unit)
        }
    }

    /// The row of `docs/cases.md`'s ranges table: keys, unit, hard range,
    /// usual range (the why column follows).
    pub fn doc_row(&self) -> String {
        let keys: Vec<String> = self.keys.iter().map(|k| format!("`{k}`")).collect();
        format!(
            "| {} | {} | {} | {} |",
            keys.join(", "),
            self.unit,
            self.hard,
            self.usual.map_or("—".to_string(), |u| u.to_string())
        )
    }
}
