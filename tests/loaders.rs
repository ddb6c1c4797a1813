//! Height and drape loaders on the real terrains and on hand-made files, scene validation,
//! procedural terrain and camera paths. Errors are checked by their message text.

mod common;

use common::{temp_dir, terrain_from_fn, terrains, Rng};
use relief::scene::{CameraPath, Keyframe, Scene};
use relief::terrain::procedural::RidgedFbm;
use relief::terrain::{geotiff, hgt, png16, Heightfield};
use std::path::Path;
use tiff::encoder::{colortype, TiffEncoder};
use tiff::tags::Tag;

/// Metres per degree on a sphere (the simple formula, independent of the loader's series).
fn sphere_metres_per_degree(lat: f64) -> (f64, f64) {
    (111_320.0 * lat.to_radians().cos(), 111_132.0)
}

fn expect_err<T: std::fmt::Debug>(what: &str, r: relief::Result<T>) -> String {
    match r {
        Ok(v) => panic!("{what}: expected an error, got Ok({v:?})"),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(what: &str, msg: &str, needles: &[&str]) {
    for n in needles {
        assert!(
            msg.contains(n),
            "{what}: error message should mention `{n}`, got: {msg}"
        );
    }
}

/// The small fields are printed in full by `expect_err`; keep big ones out of panic messages.
fn summary(f: &Heightfield) -> String {
    format!(
        "{}x{} spacing {:?} voids {}",
        f.width, f.height, f.spacing, f.voids_filled
    )
}

fn write_tiff<C: colortype::ColorType>(
    path: &Path,
    w: u32,
    h: u32,
    data: &[C::Inner],
    tags: impl FnOnce(&mut TagWriter),
) where
    [C::Inner]: tiff::encoder::TiffValue,
{
    let file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(std::io::BufWriter::new(file)).unwrap();
    let mut img = enc.new_image::<C>(w, h).unwrap();
    let mut tw = TagWriter::default();
    tags(&mut tw);
    let e = img.encoder();
    if let Some(s) = tw.pixel_scale {
        e.write_tag(Tag::ModelPixelScaleTag, &s[..]).unwrap();
    }
    if let Some(t) = tw.tiepoint {
        e.write_tag(Tag::ModelTiepointTag, &t[..]).unwrap();
    }
    if let Some(k) = &tw.geokeys {
        e.write_tag(Tag::GeoKeyDirectoryTag, &k[..]).unwrap();
    }
    if let Some(n) = &tw.nodata {
        e.write_tag(Tag::GdalNodata, n.as_str()).unwrap();
    }
    img.write_data(data).unwrap();
}

#[derive(Default)]
struct TagWriter {
    pixel_scale: Option<[f64; 3]>,
    tiepoint: Option<[f64; 6]>,
    geokeys: Option<Vec<u16>>,
    nodata: Option<String>,
}

// ---------------------------------------------------------------------------------------------
// SRTM .hgt

#[test]
fn hgt_n47e009_size_range_spacing_geo() {
    let path = terrains().join("N47E009.hgt");
    let f = hgt::load(&path).expect("N47E009.hgt loads");
    assert_eq!((f.width, f.height), (1201, 1201), "N47E009 size");
    let (lo, hi) = f.range();
    assert_eq!((lo, hi), (388.0, 2937.0), "N47E009 height range");
    assert_eq!(f.voids_filled, 0, "N47E009 has no voids");
    let (mx, my) = sphere_metres_per_degree(47.5);
    let (ex, ey) = (mx / 1200.0, my / 1200.0);
    assert!(
        (f.spacing[0] - ex).abs() < 0.5,
        "x spacing {} m, expected ≈ {ex:.3} m",
        f.spacing[0]
    );
    assert!(
        (f.spacing[1] - ey).abs() < 0.5,
        "y spacing {} m, expected ≈ {ey:.3} m",
        f.spacing[1]
    );
    assert!(
        (62.0..63.5).contains(&f.spacing[0]) && (92.0..93.2).contains(&f.spacing[1]),
        "spacing {:?}",
        f.spacing
    );
    let g = f.geo.expect("an .hgt tile has a georeference");
    assert_eq!((g.lon0, g.lat0), (9.0, 47.0), "south-west corner");
    assert!(
        (g.dlon - 1.0 / 1200.0).abs() < 1e-12 && (g.dlat - 1.0 / 1200.0).abs() < 1e-12,
        "step {g:?}"
    );
}

#[test]
fn hgt_rows_are_flipped_so_row_0_is_south() {
    let path = terrains().join("N47E009.hgt");
    let bytes = std::fs::read(&path).unwrap();
    let f = hgt::load(&path).unwrap();
    let n = 1201;
    let raw = |row: usize, col: usize| {
        i16::from_be_bytes([bytes[2 * (row * n + col)], bytes[2 * (row * n + col) + 1]]) as f32
    };
    // Sample (0, 0) is the SW corner: the last row of the file, first column.
    assert_eq!(
        f.at(0, 0),
        raw(n - 1, 0),
        "sample (0,0) must be the file's last row, first column"
    );
    assert_eq!(
        f.at(n - 1, n - 1),
        raw(0, n - 1),
        "sample (n-1,n-1) must be the file's first row, last column (NE)"
    );
    let mut rng = Rng::new(11);
    for _ in 0..1000 {
        let (i, j) = (
            rng.range(0.0, n as f64) as usize,
            rng.range(0.0, n as f64) as usize,
        );
        assert_eq!(f.at(i, j), raw(n - 1 - j, i), "sample ({i},{j})");
    }
}

#[test]
fn hgt_n43e042_size_and_range() {
    let f = hgt::load(&terrains().join("N43E042.hgt")).expect("N43E042.hgt loads");
    assert_eq!((f.width, f.height), (1201, 1201), "N43E042 size");
    assert_eq!(
        f.range(),
        (633.0, 5620.0),
        "N43E042 height range (Elbrus 5642 m summit, 3\" samples)"
    );
    let g = f.geo.unwrap();
    assert_eq!((g.lon0, g.lat0), (42.0, 43.0));
}

#[test]
fn hgt_voids_are_filled_and_counted() {
    let dir = temp_dir("hgt-voids");
    let path = dir.join("N10E010.hgt");
    let n = 1201;
    let mut v = vec![100i16; n * n];
    let voids = [(0, 0), (600, 600), (1200, 1200), (17, 999), (1200, 3)];
    for &(row, col) in &voids {
        v[row * n + col] = hgt::VOID;
    }
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_be_bytes()).collect();
    std::fs::write(&path, bytes).unwrap();
    let f = hgt::load(&path).expect("an .hgt with voids loads");
    assert_eq!(f.voids_filled, 5, "voids counted");
    for &(row, col) in &voids {
        assert_eq!(
            f.at(col, n - 1 - row),
            100.0,
            "void at file row {row} col {col} filled from 100 m neighbours"
        );
    }
    assert_eq!(
        f.range(),
        (100.0, 100.0),
        "every sample is 100 m after filling"
    );
    assert_eq!(f.geo.map(|g| (g.lon0, g.lat0)), Some((10.0, 10.0)));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn hgt_truncated_is_an_error_with_the_byte_count() {
    let dir = temp_dir("hgt-trunc");
    let path = dir.join("N47E009.hgt");
    let bytes = std::fs::read(terrains().join("N47E009.hgt")).unwrap();
    std::fs::write(&path, &bytes[..1000]).unwrap();
    let msg = expect_err("truncated .hgt", hgt::load(&path).map(|f| summary(&f)));
    assert_mentions(
        "truncated .hgt",
        &msg,
        &["1000 bytes", "truncated", &path.display().to_string()],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn hgt_without_tile_name_is_an_error_naming_the_file() {
    let dir = temp_dir("hgt-name");
    let path = dir.join("foo.hgt");
    std::fs::write(&path, vec![0u8; 1201 * 1201 * 2]).unwrap();
    let msg = expect_err("foo.hgt", hgt::load(&path).map(|f| summary(&f)));
    assert_mentions("foo.hgt", &msg, &["foo.hgt", "file name", "N47E009"]);
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// GeoTIFF

#[test]
fn geotiff_rmnp_dem_size_range_spacing() {
    let path = terrains().join("rmnp-dem.tif");
    let f = geotiff::load_heights(&path, None, None).expect("rmnp-dem.tif loads");
    assert_eq!((f.width, f.height), (152, 187), "rmnp-dem size");
    let (lo, hi) = f.range();
    assert!(
        lo >= 2281.0 && hi <= 4261.0 && hi > 4000.0,
        "rmnp-dem heights {lo}..{hi}, expected within 2281..4261"
    );
    // ModelPixelScale 0.00275° x 0.00211°, converted at the raster's centre latitude.
    let top: f64 = 40.553678069620155;
    let centre_lat = top - 0.5 * 187.0 * 0.00211;
    assert!((centre_lat - 40.3).abs() < 0.1);
    let (mx, my) = sphere_metres_per_degree(centre_lat);
    let (ex, ey) = (0.00275 * mx, 0.00211 * my);
    assert!(
        (ex - 234.0).abs() < 3.0 && (ey - 234.0).abs() < 3.0,
        "expected spacing {ex} x {ey}"
    );
    for (k, e) in [ex, ey].into_iter().enumerate() {
        let got = f.spacing[k];
        assert!(
            (got - e).abs() / e < 0.02,
            "spacing[{k}] = {got} m, expected ≈ {e:.1} m (2%)"
        );
    }
    let g = f.geo.expect("rmnp-dem is geographic: GeoRef expected");
    assert!(
        (g.lon0 - (-105.9125 + 0.5 * 0.00275)).abs() < 1e-9,
        "lon0 {}",
        g.lon0
    );
    assert!(
        (g.lat0 - (top - 186.5 * 0.00211)).abs() < 1e-9,
        "lat0 {}",
        g.lat0
    );

    // Raw samples (north row first) against the flipped grid; nodata 65535 is filled and counted.
    let mut dec =
        tiff::decoder::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()))
            .unwrap();
    let raw = match dec.read_image().unwrap() {
        tiff::decoder::DecodingResult::U16(v) => v,
        other => panic!(
            "rmnp-dem.tif should be u16, got {:?}",
            std::mem::discriminant(&other)
        ),
    };
    let nodata = raw.iter().filter(|&&v| v == 65535).count();
    assert_eq!(
        f.voids_filled, nodata,
        "GDAL_NODATA 65535 samples filled and counted"
    );
    let (w, h) = (152, 187);
    for row in 0..h {
        for col in 0..w {
            let v = raw[row * w + col];
            if v != 65535 {
                assert_eq!(
                    f.at(col, h - 1 - row),
                    v as f32,
                    "sample at file row {row} col {col}"
                );
            }
        }
    }
}

#[test]
fn geotiff_rmnp_drape() {
    let path = terrains().join("rmnp-rgb.tif");
    let d = geotiff::load_drape(&path).expect("rmnp-rgb.tif loads as a drape");
    assert_eq!((d.width, d.height), (485, 373), "drape size");
    assert_eq!(d.rgba.len(), 485 * 373 * 4);
    let g = d.geo.expect("the drape has a georeference");
    assert!(
        (g.dlon - 0.0015).abs() < 1e-9 && (g.dlat - 0.0015).abs() < 1e-9,
        "drape step {g:?}"
    );
    assert!(
        (g.lon0 - (-106.0566005603556 + 0.00075)).abs() < 1e-9,
        "drape lon0 {}",
        g.lon0
    );
    assert!(
        (g.lat0 - (40.61968153576429 - 372.5 * 0.0015)).abs() < 1e-9,
        "drape lat0 {}",
        g.lat0
    );
    // Row 0 is south: compare with an independent decode.
    let img = image::open(&path)
        .expect("image crate reads the drape")
        .to_rgb8();
    for (i, j) in [(0, 0), (484, 0), (100, 200), (484, 372), (0, 372)] {
        let p = img.get_pixel(i, 372 - j).0;
        let k = (j as usize * 485 + i as usize) * 4;
        assert_eq!(
            &d.rgba[k..k + 4],
            &[p[0], p[1], p[2], 255],
            "drape texel ({i},{j})"
        );
    }
}

#[test]
fn geotiff_corrupt_files_are_errors_naming_the_path() {
    let dir = temp_dir("tif-corrupt");
    let bytes = std::fs::read(terrains().join("rmnp-dem.tif")).unwrap();
    let cut = dir.join("cut.tif");
    std::fs::write(&cut, &bytes[..2000]).unwrap();
    let mut rng = Rng::new(5);
    let garbage = dir.join("garbage.tif");
    std::fs::write(
        &garbage,
        (0..5000).map(|_| rng.next_u64() as u8).collect::<Vec<_>>(),
    )
    .unwrap();
    // Also garbage behind a valid little-endian TIFF signature.
    let mut sig = b"II*\0".to_vec();
    sig.extend((0..5000).map(|_| rng.next_u64() as u8));
    let fake = dir.join("fake.tif");
    std::fs::write(&fake, sig).unwrap();
    for p in [&cut, &garbage, &fake] {
        let msg = expect_err(
            "corrupt TIFF heights",
            geotiff::load_heights(p, None, None).map(|f| summary(&f)),
        );
        assert_mentions("corrupt TIFF heights", &msg, &[&p.display().to_string()]);
        assert!(
            msg.to_lowercase().contains("tiff"),
            "error should say the TIFF is bad: {msg}"
        );
        let msg = expect_err(
            "corrupt TIFF drape",
            geotiff::load_drape(p).map(|d| (d.width, d.height)),
        );
        assert_mentions("corrupt TIFF drape", &msg, &[&p.display().to_string()]);
    }
    let missing = dir.join("missing.tif");
    let msg = expect_err(
        "missing TIFF",
        geotiff::load_heights(&missing, None, None).map(|f| summary(&f)),
    );
    assert_mentions("missing TIFF", &msg, &["missing.tif"]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_unsupported_layouts_are_errors() {
    let dir = temp_dir("tif-unsupported");
    let rgb = dir.join("rgb.tif");
    write_tiff::<colortype::RGB8>(&rgb, 8, 8, &[7u8; 8 * 8 * 3], |_| ());
    let msg = expect_err(
        "RGB heights",
        geotiff::load_heights(&rgb, Some([1.0, 1.0]), None).map(|f| summary(&f)),
    );
    assert_mentions("RGB heights", &msg, &["one sample per pixel", "rgb.tif"]);

    // 64-bit integer samples decode but are not a supported height format.
    let u64s = dir.join("u64.tif");
    write_tiff::<colortype::Gray64>(&u64s, 8, 8, &[7u64; 64], |_| ());
    let msg = expect_err(
        "u64 heights",
        geotiff::load_heights(&u64s, Some([1.0, 1.0]), None).map(|f| summary(&f)),
    );
    assert_mentions("u64 heights", &msg, &["u64.tif"]);
    assert!(
        msg.contains("sample format") || msg.contains("unsupported"),
        "u64 heights: {msg}"
    );

    // CMYK is neither a height map nor a drape.
    let cmyk = dir.join("cmyk.tif");
    write_tiff::<colortype::CMYK8>(&cmyk, 8, 8, &[7u8; 8 * 8 * 4], |_| ());
    let msg = expect_err(
        "CMYK drape",
        geotiff::load_drape(&cmyk).map(|d| (d.width, d.height)),
    );
    assert_mentions("CMYK drape", &msg, &["cmyk.tif", "colour type"]);

    // A grey TIFF is not a drape.
    let grey = dir.join("grey.tif");
    write_tiff::<colortype::Gray16>(&grey, 8, 8, &[7u16; 64], |_| ());
    let msg = expect_err(
        "grey drape",
        geotiff::load_drape(&grey).map(|d| (d.width, d.height)),
    );
    assert_mentions("grey drape", &msg, &["grey.tif", "RGB"]);

    // f64 samples are supported.
    let f64s = dir.join("f64.tif");
    let data: Vec<f64> = (0..64).map(|k| k as f64 * 0.5).collect();
    write_tiff::<colortype::Gray64Float>(&f64s, 8, 8, &data, |_| ());
    let f = geotiff::load_heights(&f64s, Some([2.0, 3.0]), None).expect("f64 TIFF loads");
    assert_eq!(f.spacing, [2.0, 3.0]);
    assert_eq!(
        f.at(0, 0),
        28.0,
        "f64 TIFF: sample (0,0) is the last stored row"
    );
    assert_eq!(
        f.at(7, 7),
        3.5,
        "f64 TIFF: sample (7,7) is the first stored row's last column"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_without_georeference_needs_cell_size() {
    let dir = temp_dir("tif-nogeo");
    let p = dir.join("plain.tif");
    write_tiff::<colortype::Gray16>(&p, 8, 8, &[500u16; 64], |_| ());
    let msg = expect_err(
        "no georef",
        geotiff::load_heights(&p, None, None).map(|f| summary(&f)),
    );
    assert_mentions("no georef", &msg, &["plain.tif", "cell_size"]);
    let f = geotiff::load_heights(&p, Some([10.0, 10.0]), None).unwrap();
    assert_eq!(
        (f.spacing, f.geo.is_none(), f.range()),
        ([10.0, 10.0], true, (500.0, 500.0))
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_all_nan_is_an_error() {
    let dir = temp_dir("tif-nan");
    let p = dir.join("nan.tif");
    write_tiff::<colortype::Gray32Float>(&p, 16, 16, &[f32::NAN; 256], |_| ());
    let msg = expect_err(
        "all-NaN map",
        geotiff::load_heights(&p, Some([10.0, 10.0]), None).map(|f| summary(&f)),
    );
    assert_mentions("all-NaN map", &msg, &["no valid height sample", "nan.tif"]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_partial_nan_is_filled_and_counted() {
    let dir = temp_dir("tif-partial-nan");
    let p = dir.join("partial.tif");
    let mut data: Vec<f32> = (0..256).map(|k| 1000.0 + (k % 16) as f32 * 2.0).collect();
    let holes = [0usize, 37, 38, 200, 255];
    for &k in &holes {
        data[k] = f32::NAN;
    }
    data[100] = f32::INFINITY;
    write_tiff::<colortype::Gray32Float>(&p, 16, 16, &data, |_| ());
    let f = geotiff::load_heights(&p, Some([10.0, 10.0]), None).expect("a partly NaN map loads");
    assert_eq!(
        f.voids_filled,
        holes.len() + 1,
        "NaN and inf samples counted as voids"
    );
    assert!(
        f.heights.iter().all(|h| h.is_finite()),
        "every sample finite after filling"
    );
    let (lo, hi) = f.range();
    assert!(
        lo >= 1000.0 && hi <= 1030.0,
        "filled values stay within the valid range: {lo}..{hi}"
    );
    for (k, &v) in data.iter().enumerate() {
        let (row, col) = (k / 16, k % 16);
        if v.is_finite() {
            assert_eq!(
                f.at(col, 15 - row),
                v,
                "valid sample row {row} col {col} untouched"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_nodata_tag_and_override() {
    let dir = temp_dir("tif-nodata");
    // f32 raster whose GDAL_NODATA (a decimal string) is not exactly representable in f32.
    let p = dir.join("nodata-f32.tif");
    let mut data = vec![1500.0f32; 64];
    data[9] = -9999.9;
    data[10] = -9999.9;
    write_tiff::<colortype::Gray32Float>(&p, 8, 8, &data, |t| t.nodata = Some("-9999.9".into()));
    let f = geotiff::load_heights(&p, Some([1.0, 1.0]), None).expect("loads");
    assert_eq!(
        f.voids_filled, 2,
        "f32 samples equal to GDAL_NODATA -9999.9 are voids"
    );
    assert_eq!(
        f.range(),
        (1500.0, 1500.0),
        "no-data samples must not be taken as heights"
    );
    let f = geotiff::load_heights(&p, Some([1.0, 1.0]), Some(-9999.9)).expect("loads");
    assert_eq!(
        f.voids_filled, 2,
        "the scene's nodata = -9999.9 matches f32 samples too"
    );

    // u16 raster: the scene's `nodata` overrides (and works without) the tag.
    let q = dir.join("nodata-u16.tif");
    let mut data = vec![800u16; 64];
    data[0] = 0;
    data[63] = 65535;
    write_tiff::<colortype::Gray16>(&q, 8, 8, &data, |t| t.nodata = Some("65535".into()));
    let f = geotiff::load_heights(&q, Some([1.0, 1.0]), None).unwrap();
    assert_eq!(
        (f.voids_filled, f.range()),
        (1, (0.0, 800.0)),
        "GDAL_NODATA 65535"
    );
    let f = geotiff::load_heights(&q, Some([1.0, 1.0]), Some(0.0)).unwrap();
    assert_eq!(
        (f.voids_filled, f.range()),
        (1, (800.0, 65535.0)),
        "nodata override 0"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geotiff_projected_and_geographic_tags() {
    let dir = temp_dir("tif-georef");
    let data = vec![250i16; 10 * 6];
    // Projected (GTModelType 1): spacing is the pixel scale in metres, no GeoRef.
    let p = dir.join("utm.tif");
    write_tiff::<colortype::GrayI16>(&p, 10, 6, &data, |t| {
        t.pixel_scale = Some([30.0, 25.0, 0.0]);
        t.tiepoint = Some([0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]);
        t.geokeys = Some(vec![1, 1, 0, 1, 1024, 0, 1, 1]);
    });
    let f = geotiff::load_heights(&p, None, None).expect("projected GeoTIFF loads");
    assert_eq!(
        (f.width, f.height, f.spacing, f.geo),
        (10, 6, [30.0, 25.0], None),
        "projected GeoTIFF"
    );
    assert_eq!(f.range(), (250.0, 250.0));

    // Geographic (GTModelType 2): GeoRef at the SW pixel centre, metres at the centre latitude.
    let g = dir.join("geo.tif");
    write_tiff::<colortype::GrayI16>(&g, 10, 6, &data, |t| {
        t.pixel_scale = Some([0.01, 0.02, 0.0]);
        t.tiepoint = Some([0.0, 0.0, 0.0, 7.0, -20.0, 0.0]);
        t.geokeys = Some(vec![1, 1, 0, 1, 1024, 0, 1, 2]);
    });
    let f = geotiff::load_heights(&g, None, None).expect("geographic GeoTIFF loads");
    let geo = f.geo.expect("geographic GeoTIFF has a GeoRef");
    assert!(
        (geo.lon0 - 7.005).abs() < 1e-12 && (geo.lat0 - (-20.0 - 5.5 * 0.02)).abs() < 1e-12,
        "{geo:?}"
    );
    let (mx, my) = sphere_metres_per_degree(-20.06);
    assert!(
        (f.spacing[0] / (0.01 * mx) - 1.0).abs() < 0.01,
        "x spacing {} vs {}",
        f.spacing[0],
        0.01 * mx
    );
    assert!(
        (f.spacing[1] / (0.02 * my) - 1.0).abs() < 0.01,
        "y spacing {} vs {}",
        f.spacing[1],
        0.02 * my
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// PNG and extension dispatch

#[test]
fn png16_heights_scale_offset_and_flip() {
    let dir = temp_dir("png16");
    let p = dir.join("h.png");
    let (w, h) = (7u32, 5u32);
    let raw: Vec<u16> = (0..w * h).map(|k| (k * 977 % 65536) as u16).collect();
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, raw.clone())
        .unwrap()
        .save(&p)
        .unwrap();
    let f = png16::load(&p, Some([5.0, 5.0]), 0.1, -10.0).expect("16-bit PNG loads");
    assert_eq!(
        (f.width, f.height, f.spacing, f.geo),
        (7, 5, [5.0, 5.0], None)
    );
    for row in 0..h as usize {
        for col in 0..w as usize {
            let expected = -10.0 + 0.1 * raw[row * w as usize + col] as f64;
            let got = f.at(col, h as usize - 1 - row) as f64;
            assert!(
                (got - expected).abs() < 1e-3,
                "PNG pixel row {row} col {col}: {got}, expected {expected}"
            );
        }
    }
    // Through the extension dispatch, with the same parameters.
    let g = relief::terrain::load_heightfield(&p, Some([5.0, 5.0]), None, 0.1, -10.0).unwrap();
    assert_eq!(g.heights, f.heights);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn png_errors() {
    let dir = temp_dir("png-errors");
    let p = dir.join("grey.png");
    image::GrayImage::from_pixel(4, 4, image::Luma([9]))
        .save(&p)
        .unwrap();
    let msg = expect_err(
        "PNG without cell size",
        png16::load(&p, None, 1.0, 0.0).map(|f| summary(&f)),
    );
    assert_mentions("PNG without cell size", &msg, &["cell_size", "grey.png"]);
    let f = png16::load(&p, Some([1.0, 1.0]), 1.0, 0.0).expect("8-bit grey PNG loads");
    assert_eq!(f.range(), (9.0, 9.0), "8-bit values are not stretched");

    let rgb = dir.join("rgb.png");
    image::RgbImage::from_pixel(4, 4, image::Rgb([1, 2, 3]))
        .save(&rgb)
        .unwrap();
    let msg = expect_err(
        "RGB PNG",
        png16::load(&rgb, Some([1.0, 1.0]), 1.0, 0.0).map(|f| summary(&f)),
    );
    assert_mentions("RGB PNG", &msg, &["greyscale", "rgb.png"]);

    let bad = dir.join("bad.png");
    std::fs::write(&bad, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let msg = expect_err(
        "corrupt PNG",
        png16::load(&bad, Some([1.0, 1.0]), 1.0, 0.0).map(|f| summary(&f)),
    );
    assert_mentions("corrupt PNG", &msg, &["bad.png"]);

    let unknown = dir.join("heights.xyz");
    std::fs::write(&unknown, b"1 2 3").unwrap();
    let msg = expect_err(
        "unknown extension",
        relief::terrain::load_heightfield(&unknown, None, None, 1.0, 0.0).map(|f| summary(&f)),
    );
    assert_mentions("unknown extension", &msg, &[".xyz", "heights.xyz"]);
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// Scenes

const BASE_SCENE: &str = "[terrain]\nsource = \"x.hgt\"\n[camera]\nposition = [0.0, 0.0, 1000.0]\n";

fn parse(text: &str) -> relief::Result<Scene> {
    Scene::parse(text, Path::new("x.toml"))
}

fn scene_error(what: &str, text: &str) -> String {
    expect_err(what, parse(text).map(|s| s.path))
}

#[test]
fn scene_base_text_is_valid() {
    parse(BASE_SCENE).expect("the base scene used by the error tests is valid");
}

#[test]
fn scene_errors_name_the_field() {
    let cases: [(&str, String, &[&str]); 13] = [
        ("fov 0", BASE_SCENE.replace("1000.0]", "1000.0]\nfov = 0.0"), &["camera.fov"]),
        ("fov 180", BASE_SCENE.replace("1000.0]", "1000.0]\nfov = 180.0"), &["camera.fov"]),
        ("misspelt key", BASE_SCENE.replace("[camera]\n", "[camera]\npositon = [1.0, 2.0, 3.0]\n"), &["positon"]),
        ("unknown terrain key", BASE_SCENE.replace("[terrain]\n", "[terrain]\ncolour_mode = 1\n"), &["colour_mode"]),
        ("output width 0", format!("{BASE_SCENE}[output]\nwidth = 0\n"), &["output.width"]),
        ("sun elevation 120", format!("{BASE_SCENE}[sun]\nelevation = 120.0\n"), &["sun.elevation"]),
        ("moon elevation 95", format!("{BASE_SCENE}[moon]\nazimuth = 10.0\nelevation = 95.0\n"), &["moon", "elevation"]),
        ("moon lit 1.5", format!("{BASE_SCENE}[moon]\nazimuth = 10.0\nelevation = 5.0\nilluminated = 1.5\n"), &["moon", "illuminated"]),
        ("moon azimuth nan", format!("{BASE_SCENE}[moon]\nazimuth = nan\nelevation = 5.0\n"), &["moon.azimuth"]),
        (
            "keyframes not increasing",
            format!(
                "{BASE_SCENE}[path]\nkeyframes = [\n {{ time = 0.0, position = [0.0, 0.0, 1.0] }},\n \
                 {{ time = 2.0, position = [1.0, 0.0, 1.0] }},\n {{ time = 2.0, position = [2.0, 0.0, 1.0] }},\n]\n"
            ),
            &["path.keyframes[2]", "increase"],
        ),
        ("nan position", BASE_SCENE.replace("[0.0, 0.0, 1000.0]", "[nan, 0.0, 1000.0]"), &["camera.position"]),
        (
            "source and procedural",
            BASE_SCENE.replace("[camera]", "[terrain.procedural]\nsize = 65\n[camera]"),
            &["terrain", "source", "procedural"],
        ),
        ("no terrain source", BASE_SCENE.replace("source = \"x.hgt\"\n", ""), &["terrain", "source", "procedural"]),
    ];
    for (what, text, needles) in cases {
        let msg = scene_error(what, &text);
        assert_mentions(what, &msg, needles);
    }
}

#[test]
fn scene_syntax_errors_name_the_file() {
    let msg = scene_error("bad toml", "[terrain\nsource = 1");
    assert_mentions("bad toml", &msg, &["x.toml"]);
}

#[test]
fn shipped_scenes_parse_and_validate() {
    let mut n = 0;
    for entry in std::fs::read_dir(terrains()).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let s = Scene::load(&p).unwrap_or_else(|e| panic!("{} should parse: {e}", p.display()));
        s.desc
            .validate()
            .unwrap_or_else(|e| panic!("{} should validate: {e}", p.display()));
        if let Some(src) = &s.desc.terrain.source {
            assert!(
                s.base_dir.join(src).exists(),
                "{}: source {} missing",
                p.display(),
                src.display()
            );
        }
        n += 1;
    }
    assert!(
        n >= 4,
        "expected the shipped scenes in terrains/, found {n}"
    );
}

// ---------------------------------------------------------------------------------------------
// Procedural terrain

fn fbm(size: usize, seed: u32) -> RidgedFbm {
    RidgedFbm {
        size,
        cell_size: 30.0,
        height: 2000.0,
        octaves: 6,
        wavelength: 32.0,
        seed,
    }
}

#[test]
fn procedural_is_deterministic() {
    let a = fbm(129, 3).generate().unwrap();
    let b = fbm(129, 3).generate().unwrap();
    assert_eq!((a.width, a.height, a.spacing), (129, 129, [30.0, 30.0]));
    assert!(
        a.heights
            .iter()
            .zip(&b.heights)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "same seed, different heights"
    );
    let (lo, hi) = a.range();
    assert!(
        hi > lo && lo >= 0.0 && hi <= 2000.0,
        "procedural range {lo}..{hi}"
    );
    let c = fbm(129, 4).generate().unwrap();
    assert!(
        a.heights != c.heights,
        "a different seed should give different terrain"
    );
}

#[test]
fn procedural_rejects_bad_parameters() {
    let msg = expect_err("size 1", fbm(1, 0).generate().map(|f| summary(&f)));
    assert_mentions("size 1", &msg, &["terrain.procedural.size"]);
    let msg = expect_err(
        "octaves 0",
        RidgedFbm {
            octaves: 0,
            ..fbm(9, 0)
        }
        .generate()
        .map(|f| summary(&f)),
    );
    assert_mentions("octaves 0", &msg, &["octaves"]);
    let msg = expect_err(
        "cell 0",
        RidgedFbm {
            cell_size: 0.0,
            ..fbm(9, 0)
        }
        .generate()
        .map(|f| summary(&f)),
    );
    assert_mentions("cell 0", &msg, &["cell_size"]);
}

// ---------------------------------------------------------------------------------------------
// Camera path

fn key(time: f64, position: [f64; 3], heading: f64) -> Keyframe {
    Keyframe {
        time,
        position,
        heading,
        pitch: -5.0,
        roll: 0.0,
        fov: 60.0,
    }
}

#[test]
fn camera_path_interpolates_between_keyframes() {
    let path = CameraPath {
        fps: 30.0,
        keyframes: vec![
            key(0.0, [0.0, 0.0, 1000.0], 350.0),
            key(2.0, [2000.0, 400.0, 1200.0], 10.0),
        ],
    };
    let p = path.pose_at(1.0);
    let (a, b) = (
        glam::DVec3::new(0.0, 0.0, 1000.0),
        glam::DVec3::new(2000.0, 400.0, 1200.0),
    );
    for k in 0..3 {
        assert!(
            p.position[k] > a[k] && p.position[k] < b[k],
            "pose_at(1) axis {k}: {} not between {a} and {b}",
            p.position
        );
    }
    assert!(
        (p.position - (a + b) * 0.5).length() < 1e-9,
        "two keyframes: the midpoint at half time, got {}",
        p.position
    );
    // Heading takes the short way round 0°.
    assert!(
        (p.heading.rem_euclid(360.0) - 0.0).abs() < 1e-9
            || (p.heading.rem_euclid(360.0) - 360.0).abs() < 1e-9,
        "{}",
        p.heading
    );
    assert_eq!(path.pose_at(-1.0).position, a, "clamped before the start");
    assert_eq!(path.pose_at(5.0).position, b, "clamped after the end");
}

#[test]
fn camera_frames_are_reproducible() {
    let text = format!(
        "{BASE_SCENE}[path]\nfps = 24.0\nkeyframes = [\n {{ time = 0.0, position = [0.0, 0.0, 900.0] }},\n \
         {{ time = 1.0, position = [300.0, 100.0, 950.0], heading = 30.0 }},\n \
         {{ time = 3.0, position = [900.0, 800.0, 1000.0], heading = 90.0 }},\n]\n"
    );
    let scene = parse(&text).unwrap();
    let terrain = terrain_from_fn(9, 200.0, |_, _| 0.0);
    let path = scene.desc.path.clone().unwrap();
    for frame in [0, 1, 37, 40, 71, 500] {
        let c1 = scene.camera(frame, &terrain);
        let c2 = scene.camera(frame, &terrain);
        assert_eq!(c1, c2, "frame {frame} differs between two calls");
        assert_eq!(
            c1.pose,
            path.pose_at(frame as f64 / 24.0),
            "frame {frame} is at {frame}/fps seconds"
        );
    }
    assert_ne!(
        scene.camera(10, &terrain).pose,
        scene.camera(11, &terrain).pose,
        "frames 10 and 11 should differ"
    );
}
