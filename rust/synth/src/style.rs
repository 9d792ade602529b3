//! Hairstyle presets: the numbers that shape each style of [`mod@crate::generate`].

use std::fmt;
use std::str::FromStr;

use glam::Vec3;

use crate::error::SynthError;

/// The hairstyles that the generator knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Style {
    /// Long straight hair past the shoulders, middle parting.
    Straight,
    /// Long hair in loose S-waves.
    Wavy,
    /// Tight helical curls in ringlets, shoulder length: the hard case.
    Curly,
    /// A short cut, combed back, a few centimetres long.
    Short,
    /// A chin-length bob with the ends turned under.
    Bob,
    /// Shoulder-length straight hair with volume: the roots leave the scalp steeply and the hair
    /// stands 1–3 cm off the skin over the crown and the sides, as real hair does (the other styles
    /// lie within a few millimetres of the scalp).
    Volume,
    /// Long hair parted off the middle (3 cm to the subject's left) with the parting running back to
    /// the crown, swept over to the other side in loose waves.
    SidePart,
    /// A layered cut: strands from the crown are cut to about half the length of those from the
    /// nape, so that short layers lie over long ones.
    Layered,
    /// Short hair standing up in spikes: steep roots, little gravity, strong clumps.
    Spiky,
    /// Hair drawn back over the head to a tie behind the crown, and a tail falling from it.
    Ponytail,
    /// Tight coils: round helices of 3 mm radius and 9 mm period (the curly style's are 6.5 and 22).
    Coils,
    /// Long loose curls: round helices of 12 mm radius and 60 mm period, each clump at its own phase.
    LooseCurls,
    /// Artist-made strands: the wavy style's shape as coarse polylines of 15 points, as hair assets
    /// of games and films often store it.
    Coarse,
}

impl Style {
    pub const ALL: [Style; 13] = [
        Style::Straight,
        Style::Wavy,
        Style::Curly,
        Style::Short,
        Style::Bob,
        Style::Volume,
        Style::SidePart,
        Style::Layered,
        Style::Spiky,
        Style::Ponytail,
        Style::Coils,
        Style::LooseCurls,
        Style::Coarse,
    ];

    /// The styles the reconstruction's defaults were tuned on; the others are held out for
    /// reporting (with the held-out seeds of the benchmark, docs/synthetic-captures.md).
    pub const TUNING: [Style; 6] =
        [Style::Straight, Style::Wavy, Style::Curly, Style::Short, Style::Bob, Style::Volume];

    pub fn name(self) -> &'static str {
        match self {
            Style::Straight => "straight",
            Style::Wavy => "wavy",
            Style::Curly => "curly",
            Style::Short => "short",
            Style::Bob => "bob",
            Style::Volume => "volume",
            Style::SidePart => "side_part",
            Style::Layered => "layered",
            Style::Spiky => "spiky",
            Style::Ponytail => "ponytail",
            Style::Coils => "coils",
            Style::LooseCurls => "loose_curls",
            Style::Coarse => "coarse",
        }
    }

    /// The preset of this style.
    pub fn params(self) -> StyleParams {
        let base = StyleParams {
            length: 0.45,
            length_jitter: 0.12,
            stiff_len: 0.008,
            bend_root: 0.02,
            bend_free: 0.02,
            gravity: 1.0,
            back: 0.25,
            part: 1.5,
            tip_under: 0.0,
            curl_radius: [0.0, 0.0],
            curl_period: 0.05,
            curl_ramp: 0.05,
            wave_coherence: 0.0,
            clump_size: 40.0,
            clump_strength: 0.35,
            frizz: 0.03,
            offset: 0.0015,
            volume: 0.010,
            takeoff: 0.0,
            parting_x: 0.0,
            part_back: 0.06,
            layers: 0.0,
            tie: None,
            polyline_points: 0,
        };
        let wavy = StyleParams {
            length: 0.40,
            part: 2.0,
            curl_radius: [0.014, 0.004],
            curl_period: 0.09,
            curl_ramp: 0.08,
            wave_coherence: 0.85,
            clump_strength: 0.6,
            frizz: 0.02,
            volume: 0.014,
            ..base
        };
        match self {
            Style::Straight => base,
            Style::Wavy => wavy,
            Style::Curly => StyleParams {
                length: 0.17,
                length_jitter: 0.15,
                bend_free: 0.025,
                back: 0.6,
                part: 2.5,
                curl_radius: [0.0065, 0.0065],
                curl_period: 0.022,
                curl_ramp: 0.015,
                clump_size: 60.0,
                clump_strength: 0.75,
                frizz: 0.04,
                volume: 0.025,
                ..base
            },
            Style::Short => StyleParams {
                length: 0.07,
                length_jitter: 0.2,
                stiff_len: 0.004,
                bend_root: 0.015,
                bend_free: 0.012,
                gravity: 0.6,
                back: 1.0,
                part: 1.5,
                clump_size: 30.0,
                clump_strength: 0.25,
                frizz: 0.03,
                volume: 0.004,
                ..base
            },
            Style::Bob => StyleParams {
                length: 0.17,
                length_jitter: 0.08,
                bend_free: 0.02,
                back: 0.1,
                part: 1.5,
                tip_under: 2.0,
                clump_strength: 0.3,
                volume: 0.012,
                ..base
            },
            Style::Volume => StyleParams {
                length: 0.30,
                length_jitter: 0.1,
                stiff_len: 0.02,
                bend_root: 0.05,
                back: 0.5,
                offset: 0.008,
                volume: 0.012,
                takeoff: 1.5,
                ..base
            },
            Style::SidePart => StyleParams {
                length: 0.38,
                part: 2.5,
                parting_x: 0.03,
                part_back: 0.11,
                curl_radius: [0.010, 0.003],
                curl_period: 0.10,
                curl_ramp: 0.10,
                wave_coherence: 0.7,
                clump_strength: 0.5,
                volume: 0.012,
                ..base
            },
            Style::Layered => StyleParams {
                length: 0.36,
                length_jitter: 0.15,
                layers: 0.55,
                back: 0.4,
                volume: 0.016,
                takeoff: 0.5,
                ..base
            },
            Style::Spiky => StyleParams {
                length: 0.055,
                length_jitter: 0.25,
                stiff_len: 0.03,
                bend_root: 0.08,
                bend_free: 0.05,
                gravity: 0.15,
                back: 0.5,
                part: 0.0,
                clump_size: 25.0,
                clump_strength: 0.85,
                frizz: 0.03,
                offset: 0.002,
                volume: 0.004,
                takeoff: 3.0,
                ..base
            },
            Style::Ponytail => StyleParams {
                length: 0.36,
                length_jitter: 0.06,
                stiff_len: 0.004,
                bend_root: 0.01,
                bend_free: 0.01,
                back: 0.0,
                part: 0.0,
                clump_size: 60.0,
                clump_strength: 0.3,
                frizz: 0.015,
                volume: 0.003,
                tie: Some(PONYTAIL_TIE),
                ..base
            },
            Style::Coils => StyleParams {
                length: 0.12,
                length_jitter: 0.15,
                bend_free: 0.03,
                back: 0.6,
                part: 2.5,
                curl_radius: [0.003, 0.003],
                curl_period: 0.009,
                curl_ramp: 0.008,
                clump_size: 40.0,
                clump_strength: 0.6,
                frizz: 0.05,
                volume: 0.02,
                ..base
            },
            Style::LooseCurls => StyleParams {
                length: 0.30,
                length_jitter: 0.12,
                part: 2.0,
                curl_radius: [0.012, 0.012],
                curl_period: 0.06,
                curl_ramp: 0.05,
                clump_size: 50.0,
                clump_strength: 0.7,
                frizz: 0.02,
                volume: 0.02,
                ..base
            },
            Style::Coarse => StyleParams { polyline_points: 15, ..wavy },
        }
    }
}

impl fmt::Display for Style {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Style {
    type Err = SynthError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Style::ALL.into_iter().find(|st| st.name().eq_ignore_ascii_case(s)).ok_or_else(|| {
            let names: Vec<&str> = Style::ALL.iter().map(|s| s.name()).collect();
            SynthError::Param(format!("unknown style {s:?}; use one of {}", names.join(", ")))
        })
    }
}

/// The numbers of a style. Lengths are metres; weights are relative.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StyleParams {
    /// Mean length of a strand's centreline (the strand itself is longer when it curls).
    pub length: f32,
    /// Relative spread of lengths between clumps (uniform in ±).
    pub length_jitter: f32,
    /// Arc length over which the root is stiff.
    pub stiff_len: f32,
    /// Bending length at the root: the strand turns toward its target direction over this length.
    pub bend_root: f32,
    /// Bending length past the stiff part.
    pub bend_free: f32,
    /// Weight of "down" in the target direction.
    pub gravity: f32,
    /// Weight of "toward the back of the head" (+Y).
    pub back: f32,
    /// Weight of "away from the middle parting" for roots at the front.
    pub part: f32,
    /// Weight of "toward the neck" near the tips (a bob's ends turned under).
    pub tip_under: f32,
    /// Curl radii along the two axes of the strand's frame (equal: round helix; unequal: waves).
    pub curl_radius: [f32; 2],
    /// Length of centreline per curl turn.
    pub curl_period: f32,
    /// Arc length from the root over which curls grow to full radius.
    pub curl_ramp: f32,
    /// 0: each clump's curls start at a random phase; 1: the phase follows the root's height, so
    /// that waves line up across the head.
    pub wave_coherence: f32,
    /// Mean number of strands per clump.
    pub clump_size: f32,
    /// How far the tips are pulled to their clump's guide (0: not at all, 1: onto it).
    pub clump_strength: f32,
    /// Random turning per step.
    pub frizz: f32,
    /// Least distance kept from the head.
    pub offset: f32,
    /// Largest extra distance from the head for strands that have travelled far over it (layers).
    pub volume: f32,
    /// Weight of the scalp's normal in a strand's first direction (0: the root leaves along the
    /// scalp's growth direction; larger: more steeply, as hair with volume does).
    pub takeoff: f32,
    /// x of the parting line, metres (0: a middle parting). Roots near the front are combed away
    /// from it, and clumps do not straddle it.
    pub parting_x: f32,
    /// Roots in front of this y (metres) are combed away from the parting, fading out over 8 cm
    /// behind it (0.06: the front of the head; larger: a parting that runs back to the crown).
    pub part_back: f32,
    /// Layers: strands are shorter by up to this fraction the higher their root (0: one length).
    pub layers: f32,
    /// A ponytail's tie (metres, the head's frame): strands are drawn over the head to it, then fall.
    pub tie: Option<Vec3>,
    /// Resample every strand to this many points at the end, as coarse polylines (0: keep them).
    pub polyline_points: usize,
}

/// The tie of the ponytail style on the bundled head: behind the head, a little above the ears.
pub const PONYTAIL_TIE: Vec3 = Vec3::new(0.0, 0.118, 0.06);

impl StyleParams {
    /// Checks that every number is finite and in range.
    pub fn validate(&self) -> Result<(), SynthError> {
        let positive = [
            ("length", self.length),
            ("stiff_len", self.stiff_len),
            ("bend_root", self.bend_root),
            ("bend_free", self.bend_free),
            ("curl_period", self.curl_period),
            ("curl_ramp", self.curl_ramp),
            ("clump_size", self.clump_size),
            ("offset", self.offset),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(SynthError::Param(format!("{name} must be positive and finite, got {v}")));
            }
        }
        let others = [
            ("length_jitter", self.length_jitter),
            ("gravity", self.gravity),
            ("back", self.back),
            ("part", self.part),
            ("tip_under", self.tip_under),
            ("curl_radius", self.curl_radius[0]),
            ("curl_radius", self.curl_radius[1]),
            ("clump_strength", self.clump_strength),
            ("wave_coherence", self.wave_coherence),
            ("frizz", self.frizz),
            ("volume", self.volume),
            ("takeoff", self.takeoff),
            ("layers", self.layers),
            ("part_back", self.part_back.abs()),
            ("parting_x", self.parting_x.abs()),
        ];
        for (name, v) in others {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SynthError::Param(format!("{name} must be zero or positive and finite, got {v}")));
            }
        }
        if self.tie.is_some_and(|t| !t.is_finite()) {
            return Err(SynthError::Param("tie must be a finite point".into()));
        }
        if self.polyline_points != 0 && self.polyline_points < 2 {
            return Err(SynthError::Param("polyline_points must be 0 (keep) or at least 2".into()));
        }
        if self.length_jitter >= 1.0 || self.layers >= 1.0 || self.clump_strength > 1.0 || self.wave_coherence > 1.0 {
            return Err(SynthError::Param(
                "length_jitter and layers must be below 1, clump_strength and wave_coherence at most 1".into(),
            ));
        }
        Ok(())
    }
}
