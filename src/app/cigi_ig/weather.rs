//! The host's cloud layers: Weather Control's global layers 1–3 as the frame's `[[clouds]]`.

use crate::cigi::session::{Session, CLOUD_LAYER_IDS};
use crate::scene::clouds::{self, CloudLayer};

/// Relief and cell size (m) of a Weather Control cloud type (CIGI 3.3: 1 altocumulus, 2
/// altostratus, 3 cirrocumulus, 4 cirrostratus, 5 cirrus, 6 cumulonimbus, 7 cumulus, 8
/// nimbostratus, 9 stratocumulus, 10 stratus, 11–15 IG-defined): the layered (stratiform)
/// types flat-topped with wide cells, the heaped (cumuliform) ones domed.
pub fn cloud_shape(cloud_type: u8) -> (f64, f64) {
    match cloud_type {
        1 => (0.7, 1500.0),
        2 | 8 => (0.15, 5000.0),
        3 => (0.5, 800.0),
        4 | 10 => (0.0, 5000.0),
        5 => (0.2, 3000.0),
        6 => (1.0, 6000.0),
        7 => (1.0, 2500.0),
        9 => (0.7, 3000.0),
        _ => (0.5, 2500.0),
    }
}

/// The cloud layers the host gives, or `None` when it has sent no global cloud layer (the
/// scene's `[[clouds]]` then stay). A layer is drawn while enabled with a cloud type other
/// than None (0): from its base elevation (m above MSL) through its thickness, its coverage
/// (%) and its visibility range as the visibility inside the cloud, shaped by its cloud type
/// ([`cloud_shape`]); the pattern's seed is the layer ID. Values out of `[[clouds]]`' ranges
/// are brought into them (a thickness or visibility that is not a positive number drops the
/// layer), and a layer overlapping a lower layer ID's is dropped; each drop is counted in
/// `dropped`.
pub fn host_clouds(session: &Session, dropped: &mut u64) -> Option<Vec<CloudLayer>> {
    let mut sent = false;
    let mut layers = Vec::new();
    for ((scope, _, id), w) in &session.weather {
        if *scope != 0 || !CLOUD_LAYER_IDS.contains(id) {
            continue;
        }
        sent = true;
        if !w.enable || w.cloud_type == 0 {
            continue;
        }
        let positive = |v: f32| v.is_finite() && v > 0.0;
        if !w.base_elevation.is_finite() || !positive(w.thickness) || !positive(w.visibility) {
            *dropped += 1;
            continue;
        }
        let (relief, feature) = cloud_shape(w.cloud_type);
        let layer = CloudLayer {
            base: f64::from(w.base_elevation).clamp(-1000.0, 30_000.0),
            thickness: f64::from(w.thickness).clamp(1.0, 20_000.0),
            coverage: if w.coverage.is_finite() {
                (f64::from(w.coverage) / 100.0).clamp(0.0, 1.0)
            } else {
                1.0
            },
            visibility: f64::from(w.visibility).clamp(1.0, 100_000.0),
            feature,
            seed: u32::from(*id),
            relief,
        };
        layers.push(layer);
        if clouds::validate(&layers).is_err() {
            layers.pop();
            *dropped += 1;
        }
    }
    sent.then_some(layers)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cigi::host::WeatherControl;

    fn layer(id: u8, base: f32, thickness: f32) -> WeatherControl {
        WeatherControl {
            layer_id: id,
            enable: true,
            cloud_type: 10,
            visibility: 100.0,
            coverage: 50.0,
            base_elevation: base,
            thickness,
            ..Default::default()
        }
    }

    fn host(layers: &[WeatherControl]) -> (Option<Vec<CloudLayer>>, u64) {
        let mut s = Session::new();
        for w in layers {
            s.weather
                .insert((w.scope, w.entity_region_id, w.layer_id), *w);
        }
        let mut dropped = 0;
        (host_clouds(&s, &mut dropped), dropped)
    }

    #[test]
    fn hostile_layers_are_dropped_or_brought_into_range_and_counted() {
        // No cloud layer sent: the scene's stay. Ground fog (0) is not a cloud layer.
        assert_eq!(host(&[layer(0, 0.0, 100.0)]), (None, 0));
        // A layer's values out of range are brought in; stratus is flat with 5 km cells.
        let w = WeatherControl {
            coverage: 150.0,
            visibility: 1.0e9,
            ..layer(1, 1000.0, 300.0)
        };
        let (got, dropped) = host(&[w]);
        let l = got.unwrap()[0];
        assert_eq!((l.coverage, l.visibility, dropped), (1.0, 100_000.0, 0));
        assert_eq!((l.relief, l.feature, l.seed), (0.0, 5000.0, 1));
        // Not a number, a negative thickness, and a layer overlapping layer 1: dropped.
        let (got, dropped) = host(&[
            layer(1, 1000.0, 300.0),
            layer(2, f32::NAN, 300.0),
            layer(3, 1100.0, 300.0),
        ]);
        assert_eq!((got.unwrap().len(), dropped), (1, 2));
        let (got, dropped) = host(&[layer(2, 1000.0, -5.0)]);
        assert_eq!((got.unwrap().len(), dropped), (0, 1));
        // Disabled, or cloud type None: sent, so no layers (the scene's go too).
        let off = WeatherControl {
            enable: false,
            ..layer(1, 1000.0, 300.0)
        };
        let none = WeatherControl {
            cloud_type: 0,
            ..layer(2, 3000.0, 300.0)
        };
        assert_eq!(host(&[off, none]), (Some(Vec::new()), 0));
    }
}
