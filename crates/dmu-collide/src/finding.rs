//! A replayed step's clashes and impacts, flat and named, as reports print them.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::{ClashKind, StepOutcome};

/// What a finding is: a clash of one of [`ClashKind`]'s kinds, or an impact
/// found by a sweep. Written and read as `hard`, `contact`, `soft`,
/// `impact` (the one place these names are spelled); a report with any other
/// kind is refused when read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FindingKind {
    /// The parts interpenetrate.
    Hard,
    /// The surfaces touch without penetrating.
    Contact,
    /// Apart, but closer than the clearance.
    Soft,
    /// A swept move hits the other part on the way.
    Impact,
}

impl FindingKind {
    /// `hard`, `contact`, `soft` or `impact`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Hard => "hard",
            Self::Contact => "contact",
            Self::Soft => "soft",
            Self::Impact => "impact",
        }
    }
}

impl From<ClashKind> for FindingKind {
    fn from(kind: ClashKind) -> Self {
        match kind {
            ClashKind::Hard => Self::Hard,
            ClashKind::Contact => Self::Contact,
            ClashKind::Soft => Self::Soft,
        }
    }
}

impl fmt::Display for FindingKind {
    /// The kind's name, padded as the format asks (`dmu collide`'s text lines
    /// align it in 7 columns).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.as_str())
    }
}

/// One clash or impact of a replayed step with everything a report needs: the
/// one definition of the fields of `dmu collide --json` and of the Python
/// module's `collide` (serialized with serde, so the two cannot drift apart).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding<'a> {
    /// Step number, from 0.
    pub step: usize,
    /// The step's time.
    pub t: f64,
    /// A clash's kind, or an impact.
    pub kind: FindingKind,
    /// The first part's name (a moved part).
    pub a: &'a str,
    /// The second part's name.
    pub b: &'a str,
    /// The first part's id.
    pub a_id: u32,
    /// The second part's id.
    pub b_id: u32,
    /// World distance between the parts (0 for a hard clash).
    pub distance: f64,
    /// For an impact, the fraction of the motion (0 to 1) at which it happens.
    pub toi: Option<f64>,
    /// World point of the clash or impact.
    pub point: [f64; 3],
    /// Unit world direction in which to move `b` away from `a`, for a clash
    /// (none for an impact).
    pub normal: Option<[f64; 3]>,
}

impl<'a> StepOutcome<'a> {
    /// The step's clashes, then its impacts.
    pub fn findings(&self) -> impl Iterator<Item = Finding<'a>> + use<'a> {
        let (index, t, scene, report) = (self.index, self.step.t, self.scene, self.report);
        let clashes = report.clashes.iter().map(move |c| Finding {
            step: index,
            t,
            kind: c.kind.into(),
            a: scene.part_name(c.a),
            b: scene.part_name(c.b),
            a_id: c.a.0,
            b_id: c.b.0,
            distance: c.distance,
            toi: None,
            point: c.point.to_array(),
            normal: Some(c.normal.to_array()),
        });
        let impacts = report.impacts.iter().map(move |i| Finding {
            step: index,
            t,
            kind: FindingKind::Impact,
            a: scene.part_name(i.a),
            b: scene.part_name(i.b),
            a_id: i.a.0,
            b_id: i.b.0,
            distance: i.distance,
            toi: Some(i.toi),
            point: i.point.to_array(),
            normal: None,
        });
        clashes.chain(impacts)
    }
}

#[cfg(test)]
mod tests {
    use super::FindingKind;

    /// A kind pads like a string: `dmu collide`'s text lines align on it
    /// (the enum that replaced the string printed its name unpadded).
    #[test]
    fn a_kind_pads_as_asked() {
        assert_eq!(format!("{:<7}|", FindingKind::Hard), "hard   |");
        assert_eq!(format!("{:>8}|", FindingKind::Impact), "  impact|");
        assert_eq!(FindingKind::Contact.to_string(), "contact");
    }
}
