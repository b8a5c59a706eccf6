//! A replayed step's clashes and impacts, flat and named, as reports print them.

use serde::Serialize;

use crate::StepOutcome;

/// One clash or impact of a replayed step with everything a report needs: the
/// one definition of the fields of `dmu collide --json` and of the Python
/// module's `collide` (serialized with serde, so the two cannot drift apart).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding<'a> {
    /// Step number, from 0.
    pub step: usize,
    /// The step's time.
    pub t: f64,
    /// `hard`, `contact`, `soft` or `impact`.
    pub kind: &'static str,
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
            kind: c.kind.as_str(),
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
            kind: "impact",
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
