//! A replayed step's clashes and impacts, flat and named, as reports print them.

use std::borrow::Cow;
use std::fmt;

use serde::{Deserialize, Serialize};

use crate::{ClashKind, StepOutcome};

/// Declares [`FindingKind`] and its names from one list, so that the name
/// `as_str` gives and the one serde writes and reads (`rename_all`) are one
/// spelling: a variant's name is its identifier in lower case.
macro_rules! finding_kinds {
    ($($(#[doc = $doc:literal])* $variant:ident $name:ident,)*) => {
        /// What a finding is: a clash of one of [`ClashKind`]'s kinds, or an
        /// impact found by a sweep. Written and read as `hard`, `impact`,
        /// `contact`, `soft`; a report with any other kind is refused when
        /// read.
        ///
        /// Declared worst first, so `Ord` ranks them: a pair's worst finding
        /// is its smallest kind. An impact ranks below a hard clash because
        /// the parts meet on the way and may be apart where the move ends;
        /// above a contact, because they meet at speed.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
        #[serde(rename_all = "lowercase")]
        pub enum FindingKind {
            $($(#[doc = $doc])* $variant,)*
        }

        impl FindingKind {
            /// Every kind, worst first.
            pub const ALL: [FindingKind; 4] = [$(Self::$variant),*];

            /// The kind's name, as reports write it.
            pub fn as_str(self) -> &'static str {
                match self {
                    $(Self::$variant => stringify!($name),)*
                }
            }
        }
    };
}

finding_kinds! {
    /// The parts interpenetrate.
    Hard hard,
    /// A swept move hits the other part on the way.
    Impact impact,
    /// The surfaces touch without penetrating.
    Contact contact,
    /// Apart, but closer than the clearance.
    Soft soft,
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
/// one definition of the fields of `dmu collide --json`, of the Python
/// module's `collide` and of the viewer's report reader (serialized and read
/// with serde, so they cannot drift apart).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Finding<'a> {
    /// Step number, from 0.
    pub step: usize,
    /// The step's time (0 when a report read leaves it out: a report written
    /// by hand names the step and the parts, which is all a reader needs).
    #[serde(default)]
    pub t: f64,
    /// A clash's kind, or an impact.
    pub kind: FindingKind,
    /// The first part's name (a moved part): borrowed from the scene when
    /// written, owned when read from a report.
    #[serde(borrow)]
    pub a: Cow<'a, str>,
    /// The second part's name.
    #[serde(borrow)]
    pub b: Cow<'a, str>,
    /// The first part's id (0 when a report read leaves it out: readers
    /// match parts by name, since ids are the writing model's).
    #[serde(default)]
    pub a_id: u32,
    /// The second part's id (as `a_id`).
    #[serde(default)]
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
            a: scene.part_name(c.a).into(),
            b: scene.part_name(c.b).into(),
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
            a: scene.part_name(i.a).into(),
            b: scene.part_name(i.b).into(),
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
    use super::{Finding, FindingKind};

    /// A kind pads like a string: `dmu collide`'s text lines align on it
    /// (the enum that replaced the string printed its name unpadded).
    #[test]
    fn a_kind_pads_as_asked() {
        assert_eq!(format!("{:<7}|", FindingKind::Hard), "hard   |");
        assert_eq!(format!("{:>8}|", FindingKind::Impact), "  impact|");
        assert_eq!(FindingKind::Contact.to_string(), "contact");
    }

    /// A pair's worst finding is its smallest kind.
    #[test]
    fn kinds_rank_worst_first() {
        use FindingKind::*;
        let mut kinds = [Soft, Contact, Impact, Hard];
        kinds.sort();
        assert_eq!(kinds, [Hard, Impact, Contact, Soft]);
        assert_eq!(kinds, FindingKind::ALL);
    }

    /// A kind's name is the one serde writes and reads.
    #[test]
    fn a_kind_is_named_as_serde_names_it() {
        for kind in FindingKind::ALL {
            let json = format!("\"{}\"", kind.as_str());
            assert_eq!(serde_json::to_string(&kind).unwrap(), json);
            assert_eq!(serde_json::from_str::<FindingKind>(&json).unwrap(), kind);
        }
    }

    /// What a report writes reads back the same, names with escapes included
    /// (they cannot be borrowed from the text).
    #[test]
    fn a_finding_reads_back_as_written() {
        let written = Finding {
            step: 3,
            t: 0.5,
            kind: FindingKind::Impact,
            a: "pipe \"A\"".into(),
            b: "valve".into(),
            a_id: 7,
            b_id: 9,
            distance: 0.0,
            toi: Some(0.25),
            point: [1.0, -2.0, 3e8],
            normal: None,
        };
        let text = serde_json::to_string(&written).unwrap();
        let read: Finding<'_> = serde_json::from_str(&text).unwrap();
        assert_eq!(read, written);
        assert!(serde_json::from_str::<Finding<'_>>(&text.replace("impact", "scrape")).is_err());
    }
}
