//! A model's search box as the engine's box: the family's coordinates in
//! the data's own scale as the engine's [`Chart`], and which of them span
//! decades.

use serde::{Deserialize, Serialize};

use crate::model::coords::shape_range;
use crate::model::{Coordinates, Family, SearchSpace};
use crate::optim::engine::{Chart, Space, Stepwise};

/// The map between a family's search coordinates and its canonical vectors
/// (`Coordinates`), the parameters after the family's (an effect's) as they
/// are. A pair, as a checkpoint holds it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ModelChart(pub Family, pub Coordinates);

impl Chart for ModelChart {
    fn to_canonical_into(&self, z: &[f64], theta: &mut [f64]) {
        self.1.to_native_into(self.0, z, theta);
    }

    fn coordinates_of(&self, theta: &[f64]) -> Vec<f64> {
        self.1.from_native(self.0, theta)
    }

    /// The family's canonical names, then those of the parameters after
    /// it.
    fn canonical_names(&self, names: &[String]) -> Vec<String> {
        let mut canonical = Coordinates::Native.names(self.0);
        canonical.extend(names[self.0.dim()..].iter().cloned());
        canonical
    }
}

/// Decades a log-uniform draw spans below the edge of a data-scale
/// loop-shape box (`ψ·Rⁿ/A` up to 1000: down to 10⁻³, loops that saturate
/// at a thousand times the output range, as nearly linear as a muscle's).
const SCALED_DECADES: f64 = 6.0;

impl From<&SearchSpace> for Space<ModelChart> {
    /// The loop-shape coordinates span decades (not the generalized
    /// bounded class's unloading shares, which are fractions in [−1, 1]).
    fn from(s: &SearchSpace) -> Space<ModelChart> {
        let names = s.names();
        let decades: Vec<usize> = shape_range(s.family)
            .filter(|&i| !names[i].starts_with("unload_"))
            .collect();
        let space = Space::new(s.lower.clone(), s.upper.clone(), names).with_decades(decades);
        let mut space = match s.coords {
            Coordinates::Scaled { .. } => {
                let mut space = space.with_chart(Some(ModelChart(s.family, s.coords)));
                space.drawn_decades = SCALED_DECADES;
                space
            }
            Coordinates::Native => space.with_chart(None),
        };
        if let (Some(index), Some(levels)) = (s.family.switch_index(), &s.switch_levels) {
            space.stepwise.push(Stepwise {
                index,
                preferred: levels.clone(),
                tolerance: 0.0,
            });
        }
        space
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{LinearPrior, Loop};

    #[test]
    fn canonical_names_name_what_embed_returns() {
        let prior = LinearPrior {
            a: 0.96,
            b: 25.0,
            max_abs_input: 0.4,
            max_abs_output: 40.0,
            output_range: 30.0,
            est_output_min: 5.0,
            est_output_max: 35.0,
            output_mean: 18.0,
        };
        let scaled = SearchSpace::scaled(
            Family::Classic,
            prior,
            (Loop::Bounded, Default::default()),
            false,
            &[],
        )
        .unwrap()
        .with_extra(vec!["creep.rho".into()], vec![0.9], vec![0.99], &[])
        .unwrap();
        let space = Space::from(&scaled);
        assert!(space.names.contains(&"gain".to_string()));
        let mut want: Vec<String> = Family::Classic
            .params()
            .iter()
            .map(|p| p.name.to_string())
            .collect();
        want.push("creep.rho".into());
        assert_eq!(space.canonical_names(), want);
    }
}
