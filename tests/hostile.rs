//! Bad input never panics (issue 18): hostile files through the CLI and seeded mutations of
//! small valid samples through the library loaders.
//!
//! * **Corpus replay**: every file in `tests/data/hostile/` (each tiny; written by the ignored
//!   test `write_hostile_corpus`) goes through the `relief` binary with the command that loads
//!   it, under `ulimit -v` so that no big allocation can happen unnoticed: a one-line error
//!   naming the file or field, exit status 1, no panic, nothing left in the output directory.
//!   Cases that cannot be checked in (`/dev/zero` as a tile, 6 GiB sparse files, a full disk,
//!   an output path that is a directory, SIGINT/SIGTERM) are made at test time.
//! * **Mutations**: per loader, 10,000 seeded mutations (bit flips, truncations, size fields
//!   that lie, duplicated chunks, ...) of small samples go through the loader in-process under
//!   `catch_unwind`, with a counting global allocator checking, per thread, that no single
//!   allocation exceeds the memory budget set for the test (64 MiB). The same on the full-size
//!   real files is the ignored test `mutations_of_the_real_files`.

mod common;

use common::{project_dir, temp_dir, terrains, Rng};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

// ---------------------------------------------------------------------------------------------
// Allocation accounting (per thread)

struct Counting;

thread_local! {
    static LARGEST: Cell<u64> = const { Cell::new(0) };
    static LIVE: Cell<i64> = const { Cell::new(0) };
    static PEAK: Cell<i64> = const { Cell::new(0) };
}

fn note_alloc(size: usize) {
    let _ = LARGEST.try_with(|l| {
        if size as u64 > l.get() {
            l.set(size as u64)
        }
    });
    let _ = LIVE.try_with(|l| {
        let v = l.get() + size as i64;
        l.set(v);
        let _ = PEAK.try_with(|p| {
            if v > p.get() {
                p.set(v)
            }
        });
    });
}

fn note_free(size: usize) {
    let _ = LIVE.try_with(|l| l.set(l.get() - size as i64));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            note_alloc(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            note_alloc(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        note_free(layout.size());
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            note_free(layout.size());
            note_alloc(new_size);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn reset_alloc_stats() {
    LARGEST.with(|c| c.set(0));
    LIVE.with(|c| c.set(0));
    PEAK.with(|c| c.set(0));
}

/// (largest single allocation, peak live bytes) on this thread since the last reset.
fn alloc_stats() -> (u64, u64) {
    (LARGEST.with(Cell::get), PEAK.with(Cell::get).max(0) as u64)
}

// ---------------------------------------------------------------------------------------------
// Mutations

/// The memory budget of the mutation tests: no single allocation may exceed it.
const BUDGET: u64 = 64 << 20;
/// Mutations per loader.
const CASES: usize = 10_000;

const LIES_U32: [u32; 24] = [
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    15,
    16,
    255,
    256,
    4095,
    4096,
    8000,
    65535,
    65536,
    1 << 20,
    1 << 24,
    16_000_000,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
    1 << 30,
];
const LIES_TEXT: [&str; 20] = [
    "0",
    "-1",
    "1",
    "2",
    "3",
    "8000",
    "4096",
    "65536",
    "16000000",
    "4294967296",
    "18446744073709551616",
    "99999999999999999999",
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "0.5",
    "-0",
    "",
    "1e-320",
];

/// A small valid file and, for formats with chunks, the byte ranges of its chunks.
struct Sample {
    name: String,
    bytes: Vec<u8>,
    chunks: Vec<(usize, usize)>,
}

fn sample(name: &str, bytes: Vec<u8>) -> Sample {
    Sample {
        name: name.into(),
        bytes,
        chunks: Vec::new(),
    }
}

fn pick<T: Copy>(rng: &mut Rng, v: &[T]) -> T {
    v[(rng.next_u64() % v.len() as u64) as usize]
}

fn below(rng: &mut Rng, n: usize) -> usize {
    if n == 0 {
        0
    } else {
        (rng.next_u64() % n as u64) as usize
    }
}

/// One to three of: bit flips, truncation, 4- or 2-byte size lies (either endianness),
/// duplicated chunks or byte ranges, deleted ranges, numbers in text replaced by lies, random
/// bytes, inserted garbage.
fn mutate(rng: &mut Rng, s: &Sample) -> Vec<u8> {
    let mut v = s.bytes.clone();
    let ops = 1 + below(rng, 3);
    for _ in 0..ops {
        let len = v.len();
        match below(rng, 10) {
            0 | 1 => {
                for _ in 0..1 + below(rng, 4) {
                    if len > 0 {
                        let i = below(rng, len);
                        v[i] ^= 1 << below(rng, 8);
                    }
                }
            }
            2 => v.truncate(below(rng, len + 1)),
            3 => {
                if len >= 4 {
                    let mut i = below(rng, len - 3);
                    if rng.next_u64().is_multiple_of(2) {
                        i &= !3;
                    }
                    let x = pick(rng, &LIES_U32);
                    let b = if rng.next_u64().is_multiple_of(2) {
                        x.to_le_bytes()
                    } else {
                        x.to_be_bytes()
                    };
                    v[i..i + 4].copy_from_slice(&b);
                }
            }
            4 => {
                if len >= 2 {
                    let i = below(rng, len - 1);
                    let x = pick(rng, &LIES_U32) as u16;
                    let b = if rng.next_u64().is_multiple_of(2) {
                        x.to_le_bytes()
                    } else {
                        x.to_be_bytes()
                    };
                    v[i..i + 2].copy_from_slice(&b);
                }
            }
            5 => {
                // Duplicate a chunk (or a random range) after itself or anywhere.
                let (a, b) = if !s.chunks.is_empty() && !rng.next_u64().is_multiple_of(3) {
                    pick(rng, &s.chunks)
                } else {
                    let a = below(rng, len + 1);
                    (a, (a + 1 + below(rng, 512)).min(len))
                };
                if a < b && b <= len {
                    let piece = v[a..b].to_vec();
                    let at = if rng.next_u64().is_multiple_of(2) {
                        b
                    } else {
                        below(rng, len + 1)
                    };
                    v.splice(at..at, piece);
                }
            }
            6 => {
                let a = below(rng, len + 1);
                let b = (a + 1 + below(rng, 64)).min(len);
                if a < b {
                    v.drain(a..b);
                }
            }
            7 => {
                // A number in text that lies.
                let runs: Vec<(usize, usize)> = {
                    let mut r = Vec::new();
                    let mut i = 0;
                    while i < len {
                        if v[i].is_ascii_digit() {
                            let st = i;
                            while i < len && (v[i].is_ascii_digit() || v[i] == b'.') {
                                i += 1;
                            }
                            r.push((st, i));
                        } else {
                            i += 1;
                        }
                    }
                    r
                };
                if !runs.is_empty() {
                    let (a, b) = pick(rng, &runs);
                    let lie = pick(rng, &LIES_TEXT).as_bytes().to_vec();
                    v.splice(a..b, lie);
                }
            }
            8 => {
                for _ in 0..1 + below(rng, 8) {
                    if len > 0 {
                        let i = below(rng, len);
                        v[i] = rng.next_u64() as u8;
                    }
                }
            }
            _ => {
                let at = below(rng, len + 1);
                let n = 1 + below(rng, 16);
                let junk: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
                v.splice(at..at, junk);
            }
        }
    }
    v.truncate((s.bytes.len() * 2).max(256 << 10));
    v
}

#[derive(Debug, Default)]
struct Report {
    cases: usize,
    ok: usize,
    errors: usize,
    panics: usize,
    multi_line: usize,
    largest: u64,
    peak_live: u64,
}

fn failure_dir() -> PathBuf {
    let d = project_dir().join("target").join("hostile-failures");
    let _ = std::fs::create_dir_all(&d);
    d
}

/// The memory budget is process-wide: runs with the small-sample budget share it, a run with
/// another budget (the real files) has it to itself.
static BUDGET_LOCK: std::sync::RwLock<()> = std::sync::RwLock::new(());

/// Runs `cases` mutations of `samples` through `load` and checks: no panic, one-line errors,
/// no single allocation over [`BUDGET`] (the loaders run with that memory budget).
fn fuzz(
    loader: &str,
    seed: u64,
    cases: usize,
    samples: &[Sample],
    load: impl Fn(&[u8]) -> relief::Result<()>,
) -> Report {
    let _shared = BUDGET_LOCK.read().unwrap_or_else(|e| e.into_inner());
    fuzz_with_budget(loader, seed, cases, samples, BUDGET, load)
}

fn fuzz_with_budget(
    loader: &str,
    seed: u64,
    cases: usize,
    samples: &[Sample],
    budget: u64,
    load: impl Fn(&[u8]) -> relief::Result<()>,
) -> Report {
    relief::fileio::set_memory_budget(budget);
    for s in samples {
        if let Err(e) = load(&s.bytes) {
            panic!("{loader}: the sample {} does not load: {e}", s.name);
        }
    }
    let mut rng = Rng::new(seed);
    let mut rep = Report::default();
    let mut examples = Vec::new();
    for case in 0..cases {
        let s = &samples[case % samples.len()];
        let m = mutate(&mut rng, s);
        reset_alloc_stats();
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| load(&m)));
        let (largest, peak) = alloc_stats();
        rep.cases += 1;
        rep.largest = rep.largest.max(largest);
        rep.peak_live = rep.peak_live.max(peak);
        let mut keep = false;
        match r {
            Ok(Ok(())) => rep.ok += 1,
            Ok(Err(e)) => {
                rep.errors += 1;
                let msg = e.to_string();
                if msg.contains('\n') {
                    rep.multi_line += 1;
                    keep = true;
                    if examples.len() < 3 {
                        examples.push(format!("case {case}: {msg}"));
                    }
                }
            }
            Err(_) => {
                rep.panics += 1;
                keep = true;
                if examples.len() < 3 {
                    examples.push(format!("case {case} panicked"));
                }
            }
        }
        if largest > budget {
            keep = true;
            if examples.len() < 3 {
                examples.push(format!("case {case} allocated {largest} bytes at once"));
            }
        }
        if keep {
            let _ = std::fs::write(failure_dir().join(format!("{loader}-{case}.bin")), &m);
        }
    }
    eprintln!(
        "{loader}: {} mutations: {} loaded, {} refused, {} panics, {} multi-line errors; \
         largest allocation {} bytes, peak live {} bytes",
        rep.cases, rep.ok, rep.errors, rep.panics, rep.multi_line, rep.largest, rep.peak_live
    );
    assert!(
        rep.panics == 0 && rep.multi_line == 0 && rep.largest <= budget,
        "{loader}: {rep:?}; examples (files in target/hostile-failures): {examples:#?}"
    );
    rep
}

// ---------------------------------------------------------------------------------------------
// Small valid samples

fn hgt_sample() -> Vec<u8> {
    (0..33 * 33)
        .flat_map(|k| {
            let (i, j) = (k % 33, k / 33);
            let v: i16 = if k == 100 || k == 500 {
                -32768
            } else {
                (400 + 7 * i + 3 * j) as i16
            };
            v.to_be_bytes()
        })
        .collect()
}

fn tiff_sample<C: tiff::encoder::colortype::ColorType>(
    data: &[C::Inner],
    compression: tiff::encoder::Compression,
) -> Vec<u8>
where
    [C::Inner]: tiff::encoder::TiffValue,
{
    use tiff::tags::Tag;
    let mut out = std::io::Cursor::new(Vec::new());
    let mut enc = tiff::encoder::TiffEncoder::new(&mut out)
        .unwrap()
        .with_compression(compression);
    let mut img = enc.new_image::<C>(16, 16).unwrap();
    let e = img.encoder();
    e.write_tag(Tag::ModelPixelScaleTag, &[0.001f64, 0.001, 0.0][..])
        .unwrap();
    e.write_tag(
        Tag::ModelTiepointTag,
        &[0.0f64, 0.0, 0.0, 9.0, 47.0, 0.0][..],
    )
    .unwrap();
    e.write_tag(
        Tag::GeoKeyDirectoryTag,
        &[1u16, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, 1][..],
    )
    .unwrap();
    e.write_tag(Tag::GdalNodata, "-9999").unwrap();
    img.write_data(data).unwrap();
    out.into_inner()
}

fn tiff_samples() -> Vec<Sample> {
    use tiff::encoder::{colortype, Compression, DeflateLevel};
    let u16s: Vec<u16> = (0..256).map(|k| 1000 + k as u16 * 3).collect();
    let f32s: Vec<f32> = (0..256)
        .map(|k| if k == 17 { -9999.0 } else { k as f32 * 0.5 })
        .collect();
    let i16s: Vec<i16> = (0..256).map(|k| k as i16 - 100).collect();
    vec![
        sample(
            "u16-plain.tif",
            tiff_sample::<colortype::Gray16>(&u16s, Compression::Uncompressed),
        ),
        sample(
            "f32-deflate.tif",
            tiff_sample::<colortype::Gray32Float>(
                &f32s,
                Compression::Deflate(DeflateLevel::Balanced),
            ),
        ),
        sample(
            "i16-lzw.tif",
            tiff_sample::<colortype::GrayI16>(&i16s, Compression::Lzw),
        ),
        sample(
            "u16-packbits.tif",
            tiff_sample::<colortype::Gray16>(&u16s, Compression::Packbits),
        ),
    ]
}

fn png_bytes(img: image::DynamicImage) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn png_samples() -> Vec<Sample> {
    let g16 = image::ImageBuffer::from_fn(16, 16, |x, y| image::Luma([(x * 300 + y * 7) as u16]));
    let g8 = image::GrayImage::from_fn(16, 16, |x, y| image::Luma([(x * 9 + y) as u8]));
    vec![
        sample(
            "grey16.png",
            png_bytes(image::DynamicImage::ImageLuma16(g16)),
        ),
        sample("grey8.png", png_bytes(image::DynamicImage::ImageLuma8(g8))),
    ]
}

fn rgba_png_sample() -> Vec<u8> {
    let img = image::RgbaImage::from_fn(16, 16, |x, y| {
        image::Rgba([x as u8 * 16, y as u8 * 16, 7, 255])
    });
    png_bytes(image::DynamicImage::ImageRgba8(img))
}

fn gzip(data: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(data).unwrap();
    e.finish().unwrap()
}

fn nrrd_samples() -> Vec<Sample> {
    let u8s: Vec<u8> = (0..6 * 5 * 4).map(|k| (k * 2) as u8).collect();
    let i16s: Vec<u8> = (0..6 * 5 * 4)
        .flat_map(|k| ((k as i16) * 10 - 300).to_be_bytes())
        .collect();
    let f32s: Vec<u8> = (0..4 * 3 * 3)
        .flat_map(|k| (k as f32 * 0.25).to_le_bytes())
        .collect();
    vec![
        sample(
            "u8-gzip.nrrd",
            [
                b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 6 5 4\nspacings: 1 1 2\nencoding: gzip\n\n"
                    .to_vec(),
                gzip(&u8s),
            ]
            .concat(),
        ),
        sample(
            "i16-raw.nrrd",
            [
                b"NRRD0005\n# comment\ntype: short\ndimension: 3\nsizes: 6 5 4\nendian: big\nencoding: raw\nspace: left-posterior-superior\nspace directions: (1,0,0) (0,1.5,0) (0,0,2)\n\n".to_vec(),
                i16s,
            ]
            .concat(),
        ),
        sample(
            "f32-skip.nrrd",
            [
                b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4 3 3\nbyte skip: 4\nencoding: raw\n\n"
                    .to_vec(),
                vec![9, 9, 9, 9],
                f32s,
            ]
            .concat(),
        ),
    ]
}

/// A `.vox` chunk.
fn chunk(id: &[u8; 4], content: &[u8], children: &[u8]) -> Vec<u8> {
    let mut v = id.to_vec();
    v.extend((content.len() as i32).to_le_bytes());
    v.extend((children.len() as i32).to_le_bytes());
    v.extend(content);
    v.extend(children);
    v
}

fn vox_dict(pairs: &[(&str, &str)]) -> Vec<u8> {
    let mut v = (pairs.len() as i32).to_le_bytes().to_vec();
    for (k, val) in pairs {
        for s in [k, val] {
            v.extend((s.len() as i32).to_le_bytes());
            v.extend(s.as_bytes());
        }
    }
    v
}

fn vox_size(s: [i32; 3]) -> Vec<u8> {
    chunk(
        b"SIZE",
        &s.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>(),
        &[],
    )
}

fn vox_xyzi(voxels: &[[u8; 4]]) -> Vec<u8> {
    let mut c = (voxels.len() as i32).to_le_bytes().to_vec();
    for v in voxels {
        c.extend(v);
    }
    chunk(b"XYZI", &c, &[])
}

fn vox_trn(node: i32, child: i32, frame: &[(&str, &str)]) -> Vec<u8> {
    let mut c = node.to_le_bytes().to_vec();
    c.extend(vox_dict(&[]));
    c.extend(child.to_le_bytes());
    c.extend((-1i32).to_le_bytes());
    c.extend((-1i32).to_le_bytes());
    c.extend(1i32.to_le_bytes());
    c.extend(vox_dict(frame));
    chunk(b"nTRN", &c, &[])
}

fn vox_grp(node: i32, children: &[i32]) -> Vec<u8> {
    let mut c = node.to_le_bytes().to_vec();
    c.extend(vox_dict(&[]));
    c.extend((children.len() as i32).to_le_bytes());
    for ch in children {
        c.extend(ch.to_le_bytes());
    }
    chunk(b"nGRP", &c, &[])
}

fn vox_shp(node: i32, models: &[(i32, Option<&str>)]) -> Vec<u8> {
    let mut c = node.to_le_bytes().to_vec();
    c.extend(vox_dict(&[]));
    c.extend((models.len() as i32).to_le_bytes());
    for (id, f) in models {
        c.extend(id.to_le_bytes());
        match f {
            Some(f) => c.extend(vox_dict(&[("_f", f)])),
            None => c.extend(vox_dict(&[])),
        }
    }
    chunk(b"nSHP", &c, &[])
}

fn vox_file(children: &[Vec<u8>]) -> Vec<u8> {
    let mut v = b"VOX ".to_vec();
    v.extend(150i32.to_le_bytes());
    v.extend(chunk(b"MAIN", &[], &children.concat()));
    v
}

/// Byte ranges of the chunks inside MAIN.
fn vox_chunks(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut pos = 20;
    while pos + 12 <= bytes.len() {
        let n = i32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let m = i32::from_le_bytes(bytes[pos + 8..pos + 12].try_into().unwrap()) as usize;
        let end = (pos + 12 + n + m).min(bytes.len());
        out.push((pos, end));
        pos = end;
    }
    out
}

fn graph_vox_sample() -> Vec<u8> {
    let mut pal = Vec::new();
    for i in 0..256u32 {
        pal.extend([i as u8, 255 - i as u8, 40, 255]);
    }
    vox_file(&[
        vox_size([3, 2, 2]),
        vox_xyzi(&[[0, 0, 0, 1], [1, 0, 0, 2], [2, 1, 1, 3]]),
        vox_size([2, 2, 2]),
        vox_xyzi(&[[0, 0, 0, 4], [1, 1, 1, 5]]),
        vox_trn(0, 1, &[]),
        vox_grp(1, &[2, 4]),
        vox_trn(2, 3, &[("_t", "3 0 -1"), ("_r", "20")]),
        vox_shp(3, &[(0, Some("0")), (1, Some("2"))]),
        vox_trn(4, 5, &[("_t", "-2 4 0")]),
        vox_shp(5, &[(1, None)]),
        chunk(b"RGBA", &pal, &[]),
        chunk(b"MATL", &[1, 2, 3, 4], &[]),
    ])
}

fn vox_samples() -> Vec<Sample> {
    let deer = std::fs::read(terrains().join("voxels/deer.vox")).unwrap();
    let graph = graph_vox_sample();
    vec![
        Sample {
            name: "deer.vox".into(),
            chunks: vox_chunks(&deer),
            bytes: deer,
        },
        Sample {
            name: "graph.vox".into(),
            chunks: vox_chunks(&graph),
            bytes: graph,
        },
    ]
}

fn rvs_samples() -> Vec<Sample> {
    use relief::voxel::{segment, vox::VoxFile, Voxel, VoxelModel};
    let deer = VoxFile::load(&terrains().join("voxels/deer.vox"))
        .unwrap()
        .frames()
        .unwrap()
        .remove(0);
    let mut palette = vec![[0u8; 4]; 256];
    palette[1] = [200, 10, 10, 255];
    palette[2] = [10, 200, 10, 255];
    let voxels = vec![
        Voxel {
            pos: [0, 0, 0],
            index: 1,
        },
        Voxel {
            pos: [0, 0, 1],
            index: 2,
        },
        Voxel {
            pos: [2, 1, 3],
            index: 1,
        },
    ];
    let mut small = VoxelModel::new("small", [3, 2, 4], palette, voxels).unwrap();
    small.extra_sizes = vec![2, 1];
    small.extra = (0..9).collect();
    vec![
        sample("deer.rvs", segment::encode(&deer)),
        sample("small.rvs", segment::encode(&small)),
    ]
}

fn pfm_samples() -> Vec<Sample> {
    let mut colour = b"PF\n8 6\n-1.0\n".to_vec();
    for k in 0..8 * 6 * 3 {
        colour.extend((k as f32 * 0.1).to_le_bytes());
    }
    let mut grey = b"Pf\n5 4\n1.0\n".to_vec();
    for k in 0..5 * 4 {
        grey.extend((k as f32).to_be_bytes());
    }
    vec![sample("colour.pfm", colour), sample("grey.pfm", grey)]
}

fn bourke_samples() -> Vec<Sample> {
    let mut rect = "2\n4 3\n".to_string();
    for j in 0..3 {
        for i in 0..4 {
            rect += &format!(
                "{} {} {} {} {}\n",
                -1.0 + i as f64 * 0.5,
                -1.0 + j as f64,
                i as f64 / 3.0,
                j as f64 / 2.0,
                if i == 3 && j == 2 { -1.0 } else { 1.0 }
            );
        }
    }
    let polar = "1\n2 2\n0 0 0.5 0.5 1\n1 0 0.6 0.5 1\n0 1 0.5 0.6 1\n1 1 0.6 0.6 0.5\n";
    vec![
        sample("rect.data", rect.into_bytes()),
        sample("polar.data", polar.as_bytes().to_vec()),
    ]
}

const SCENE_SAMPLE: &str = "[terrain]\nsource = \"N47E009.hgt\"\nvertical_scale = 1.5\n\
[sun]\nazimuth = 200.0\nelevation = -12.0\n[moon]\nazimuth = 100.0\nelevation = 20.0\nilluminated = 0.6\n\
[sky]\ntwilight = true\n[fog]\nvisibility = 20000.0\n\
[camera]\nposition = [100.0, 200.0, 1500.0]\nheading = 30.0\npitch = -10.0\nfov = 60.0\n\
[output]\nwidth = 64\nheight = 48\n\
[path]\nfps = 30.0\nkeyframes = [\n { time = 0.0, position = [0.0, 0.0, 1000.0] },\n { time = 2.0, position = [100.0, 0.0, 1100.0], heading = 10.0 },\n]\n\
[[objects]]\nname = \"ball\"\nshape = \"ellipsoid\"\nradii = [10.0, 10.0, 10.0]\nposition = [0.0, 0.0, 1200.0]\n";

/// A small procedural scene for the CLI runs, with `extra` appended (file paths absolute).
fn cli_scene(dir: &Path, name: &str, terrain: &str, extra: &str) -> PathBuf {
    let p = dir.join(name);
    let text = format!(
        "{terrain}\n[camera]\nposition = [300.0, 300.0, 400.0]\nheading = 45.0\npitch = -20.0\nfov = 60.0\n\
         [output]\nwidth = 32\nheight = 24\n{extra}"
    );
    std::fs::write(&p, text).unwrap();
    p
}

const PROCEDURAL: &str = "[terrain.procedural]\nsize = 65\ncell_size = 10.0\nheight = 100.0\noctaves = 2\nwavelength = 200.0\nseed = 1\n";

// ---------------------------------------------------------------------------------------------
// Mutation tests (in-process)

#[test]
fn mutations_hgt() {
    let p = Path::new("N47E009.hgt");
    fuzz("hgt", 1, CASES, &[sample("33x33.hgt", hgt_sample())], |b| {
        relief::terrain::hgt::decode_square(b, 33, p).map(|_| ())
    });
}

#[test]
fn mutations_geotiff() {
    let p = Path::new("sample.tif");
    fuzz("geotiff", 2, CASES, &tiff_samples(), |b| {
        relief::terrain::geotiff::decode_heights(b, p, None, None).map(|_| ())
    });
}

#[test]
fn mutations_png_heights() {
    let p = Path::new("sample.png");
    fuzz("png", 3, CASES, &png_samples(), |b| {
        relief::terrain::png16::decode(b, p, Some([10.0, 10.0]), 0.5, 100.0).map(|_| ())
    });
}

#[test]
fn mutations_png_images_drape_and_dome_master() {
    let p = Path::new("dome.png");
    fuzz(
        "image",
        4,
        CASES,
        &[sample("rgba.png", rgba_png_sample())],
        |b| relief::fileio::decode_image(b, p, 4).map(|i| drop(i.to_rgba8())),
    );
}

#[test]
fn mutations_nrrd() {
    let p = Path::new("sample.nrrd");
    fuzz("nrrd", 5, CASES, &nrrd_samples(), |b| {
        relief::volume::nrrd::decode(b, p, None).map(|_| ())
    });
}

#[test]
fn mutations_raw_volume() {
    // Header and data mutate in turn (files, as the loader follows the header's path).
    let dir = temp_dir("mut-raw");
    let header = b"file = \"v.raw\"\ndims = [4, 3, 2]\ntype = \"uint16\"\nendian = \"big\"\nspacing = [2.0, 2.0, 4.0]\nunits = \"mm\"\n".to_vec();
    let data: Vec<u8> = (0..24u16).flat_map(|v| (v * 1000).to_be_bytes()).collect();
    let gz_header = b"file = \"v.raw.gz\"\ndims = [4, 3, 2]\ntype = \"int16\"\n".to_vec();
    let gz = gzip(&data);
    let h = dir.join("v.toml");
    let counter = Cell::new(0usize);
    let samples = [
        sample("header", header.clone()),
        sample("data", data.clone()),
        sample("gz-header", gz_header.clone()),
        sample("gz-data", gz.clone()),
    ];
    fuzz("raw", 6, CASES, &samples, |b| {
        let k = counter.get();
        counter.set(k + 1);
        // Which sample this case mutates (fuzz() cycles through them; the first calls load the
        // samples themselves in the same order).
        let which = if k < samples.len() {
            k
        } else {
            (k - samples.len()) % samples.len()
        };
        let (hd, raw, gzd): (&[u8], &[u8], &[u8]) = match which {
            0 => (b, &data, &gz),
            1 => (&header, b, &gz),
            2 => (b, &data, &gz),
            _ => (&gz_header, &data, b),
        };
        std::fs::write(&h, hd).unwrap();
        std::fs::write(dir.join("v.raw"), raw).unwrap();
        std::fs::write(dir.join("v.raw.gz"), gzd).unwrap();
        relief::volume::raw::load(&h, None).map(|_| ())
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mutations_vox() {
    let p = Path::new("sample.vox");
    fuzz("vox", 7, CASES, &vox_samples(), |b| {
        relief::voxel::vox::VoxFile::parse(b, p)?
            .frames()
            .map(|_| ())
    });
}

#[test]
fn mutations_rvs() {
    let p = Path::new("sample.rvs");
    fuzz("rvs", 8, CASES, &rvs_samples(), |b| {
        relief::voxel::segment::decode(b, p).map(|_| ())
    });
}

#[test]
fn mutations_pfm() {
    let p = Path::new("sample.pfm");
    fuzz("pfm", 9, CASES, &pfm_samples(), |b| {
        relief::display::warp::parse_pfm(b, p, relief::display::warp::RowOrder::BottomToTop)
            .map(|_| ())
    });
}

#[test]
fn mutations_bourke_mesh() {
    let p = Path::new("sample.data");
    fuzz("bourke", 10, CASES, &bourke_samples(), |b| {
        let text = relief::fileio::text_from_bytes(p, b.to_vec())?;
        relief::display::warp::parse_bourke(&text, p).map(|_| ())
    });
}

#[test]
fn mutations_scene_toml() {
    let p = Path::new("scene.toml");
    fuzz(
        "scene",
        11,
        CASES,
        &[sample("scene.toml", SCENE_SAMPLE.as_bytes().to_vec())],
        |b| {
            let text = relief::fileio::text_from_bytes(p, b.to_vec())?;
            relief::scene::Scene::parse(&text, p).map(|_| ())
        },
    );
}

#[test]
fn mutations_display_toml() {
    let dir = temp_dir("mut-display");
    let p = dir.join("display.toml");
    let samples: Vec<Sample> = ["dome-fisheye.toml", "cylinder-3ch.toml", "mirror-dome.toml"]
        .iter()
        .map(|n| {
            sample(
                n,
                std::fs::read(project_dir().join("distortion").join(n)).unwrap(),
            )
        })
        .collect();
    fuzz("display", 12, CASES, &samples, |b| {
        std::fs::write(&p, b).unwrap();
        relief::display::DisplayConfig::load(&p).map(|_| ())
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mutations_path_script_and_eye_csv() {
    use relief::app::view::motion::{read_path_csv, ControlScript, EyeFeed};
    let dir = temp_dir("mut-csv");
    let p = dir.join("in.csv");
    let path_csv = "time,x,y,alt,heading,pitch,roll\n0,0,0,1000,0,0,0\n0.5,10,0,1001,1,0,0\n1.5,20,5,1002,2,1,-1\n";
    let script =
        "time,throttle,pitch,roll,yaw\n0,0.5,0,0,0\n1,1,0.2,-0.1,0\n2.5,0.7,-0.3,0.2,0.1\n";
    let eyes = "# eye\nx,y,z\n0,0,0\n0.1,-0.05,0.02\n\n0.2,0,0\n";
    fuzz(
        "path-csv",
        13,
        CASES,
        &[sample("path.csv", path_csv.into())],
        |b| {
            std::fs::write(&p, b).unwrap();
            read_path_csv(&p, 60.0).map(|_| ())
        },
    );
    fuzz(
        "script-csv",
        14,
        CASES,
        &[sample("script.csv", script.into())],
        |b| {
            std::fs::write(&p, b).unwrap();
            ControlScript::load(&p).map(|_| ())
        },
    );
    fuzz(
        "eye-csv",
        15,
        CASES,
        &[sample("eyes.csv", eyes.into())],
        |b| {
            std::fs::write(&p, b).unwrap();
            EyeFeed::load(&p).map(|_| ())
        },
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A small terrain database: a 33x33 geographic GeoTIFF (two voids) compiled with `tile`
/// cells a side; its chunks are the header, the index and each tile's blob.
fn db_sample(tile: u32) -> Sample {
    use tiff::encoder::{colortype, TiffEncoder};
    use tiff::tags::Tag;
    let dir = temp_dir(&format!("db-sample-{tile}"));
    let src = dir.join("sample.tif");
    {
        let file = std::fs::File::create(&src).unwrap();
        let mut enc = TiffEncoder::new(std::io::BufWriter::new(file)).unwrap();
        let mut img = enc.new_image::<colortype::Gray32Float>(33, 33).unwrap();
        let e = img.encoder();
        let step = 1.0 / 1200.0;
        e.write_tag(Tag::ModelPixelScaleTag, &[step, step, 0.0][..])
            .unwrap();
        e.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, 9.01, 47.03, 0.0][..],
        )
        .unwrap();
        e.write_tag(
            Tag::GeoKeyDirectoryTag,
            &[1u16, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, 2][..],
        )
        .unwrap();
        let data: Vec<f32> = (0..33 * 33)
            .map(|k| match k {
                100 | 500 => f32::NAN,
                _ => (400 + 7 * (k % 33) + 3 * (k / 33)) as f32,
            })
            .collect();
        img.write_data(&data).unwrap();
    }
    let out = dir.join("sample.reliefdb");
    let opts = relief::db::BuildOptions { tile };
    relief::db::build(&out, &[src], &opts, &|_, _| {}).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    let d = relief::db::Database::open(&out).unwrap();
    let h = d.header();
    let mut chunks = vec![
        (0, h.index_offset as usize),
        (h.index_offset as usize, h.data_offset as usize),
    ];
    chunks.extend(
        d.entries()
            .iter()
            .map(|e| (e.offset as usize, (e.offset + e.length as u64) as usize)),
    );
    let _ = std::fs::remove_dir_all(&dir);
    Sample {
        name: format!("sample-{tile}.reliefdb"),
        bytes,
        chunks,
    }
}

/// Makes a mutated database's checksums right again where its structure still allows (the
/// header's, each blob's named by a readable index entry, the index's), so that mutations
/// reach the parser and the tile decoder behind the CRCs.
fn repair_db_checksums(b: &mut [u8]) {
    let u32_at = |b: &[u8], k: usize| u32::from_le_bytes(b[k..k + 4].try_into().unwrap());
    let u64_at = |b: &[u8], k: usize| u64::from_le_bytes(b[k..k + 8].try_into().unwrap());
    if b.len() < 96 {
        return;
    }
    let hl = u32_at(b, 12) as usize;
    if !(8..=b.len()).contains(&hl) {
        return;
    }
    let c = crc32fast::hash(&b[..hl - 4]);
    b[hl - 4..hl].copy_from_slice(&c.to_le_bytes());
    let count = u64_at(b, 32);
    let end = (hl as u64).saturating_add(count.saturating_mul(40));
    if end.saturating_add(4) > b.len() as u64 {
        return;
    }
    let end = end as usize;
    for k in (hl..end).step_by(40) {
        let (off, len) = (u64_at(b, k + 16), u32_at(b, k + 24) as u64);
        if off.saturating_add(len) <= b.len() as u64 {
            let c = crc32fast::hash(&b[off as usize..(off + len) as usize]);
            b[k + 28..k + 32].copy_from_slice(&c.to_le_bytes());
        }
    }
    let c = crc32fast::hash(&b[hl..end]);
    b[end..end + 4].copy_from_slice(&c.to_le_bytes());
}

/// Opens a database from bytes, reads every tile and the window over its whole extent.
fn load_db(bytes: Vec<u8>) -> relief::Result<()> {
    let d = relief::db::Database::from_bytes(Path::new("sample.reliefdb"), bytes)?;
    for e in d.entries() {
        d.tile(e.id)?;
    }
    let spec = relief::db::window::resolve(&d, None, None)?;
    relief::db::window::read(&d, &spec).map(|_| ())
}

#[test]
fn mutations_database() {
    let samples = [db_sample(16), db_sample(32)];
    fuzz("database", 13, CASES, &samples, |b| load_db(b.to_vec()));
    // Behind the checksums: the same mutations with the CRCs made right again.
    fuzz("database-crc-repaired", 14, CASES, &samples, |b| {
        let mut v = b.to_vec();
        repair_db_checksums(&mut v);
        load_db(v)
    });
}

/// The same on the full-size real files (slow: run with `--ignored`; prints its counts).
#[test]
#[ignore]
fn mutations_of_the_real_files() {
    // The real files need more than the small samples' budget: 1 GiB, with the budget to itself.
    let _alone = BUDGET_LOCK.write().unwrap_or_else(|e| e.into_inner());
    let fuzz = |loader: &str,
                seed: u64,
                cases: usize,
                samples: &[Sample],
                load: &dyn Fn(&[u8]) -> relief::Result<()>| {
        fuzz_with_budget(loader, seed, cases, samples, 1 << 30, load)
    };
    let t = terrains();
    let read = |p: &str| std::fs::read(t.join(p)).unwrap();
    let n = 500;
    let hgt = t.join("N47E009.hgt");
    fuzz(
        "real-hgt",
        21,
        n,
        &[sample("N47E009.hgt", read("N47E009.hgt"))],
        &|b| relief::terrain::hgt::decode(b, &hgt).map(|_| ()),
    );
    let tif = t.join("rmnp-dem.tif");
    fuzz(
        "real-geotiff",
        22,
        n,
        &[sample("rmnp-dem.tif", read("rmnp-dem.tif"))],
        &|b| relief::terrain::geotiff::decode_heights(b, &tif, None, None).map(|_| ()),
    );
    let nrrd = t.join("volumes/mni152_t1.nrrd");
    fuzz(
        "real-nrrd",
        23,
        n,
        &[sample("mni152_t1.nrrd", read("volumes/mni152_t1.nrrd"))],
        &|b| relief::volume::nrrd::decode(b, &nrrd, None).map(|_| ()),
    );
    for name in ["axes.vox", "deer.vox", "tree.vox"] {
        let bytes = read(&format!("voxels/{name}"));
        let s = Sample {
            name: name.into(),
            chunks: vox_chunks(&bytes),
            bytes,
        };
        let p = t.join("voxels").join(name);
        fuzz(&format!("real-{name}"), 24, n, &[s], &|b| {
            relief::voxel::vox::VoxFile::parse(b, &p)?
                .frames()
                .map(|_| ())
        });
    }
}

// ---------------------------------------------------------------------------------------------
// The hostile corpus (tests/data/hostile/)

fn corpus_dir() -> PathBuf {
    project_dir().join("tests/data/hostile")
}

fn png_chunk(out: &mut Vec<u8>, ty: &[u8; 4], data: &[u8]) {
    out.extend((data.len() as u32).to_be_bytes());
    out.extend(ty);
    out.extend(data);
    let mut crc = flate2::Crc::new();
    crc.update(ty);
    crc.update(data);
    out.extend(crc.sum().to_be_bytes());
}

/// A PNG that declares `w x h` and holds a few bytes of image data.
fn png_header_only(w: u32, h: u32, depth: u8, colour: u8) -> Vec<u8> {
    let mut v = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([depth, colour, 0, 0, 0]);
    png_chunk(&mut v, b"IHDR", &ihdr);
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&[0u8; 64]).unwrap();
    png_chunk(&mut v, b"IDAT", &z.finish().unwrap());
    png_chunk(&mut v, b"IEND", &[]);
    v
}

/// A little-endian TIFF that declares `w x h` grey samples and holds 64 bytes of data.
fn tiff_header_only(w: u32, h: u32, bits: u16, compression: u16) -> Vec<u8> {
    let entries: [(u16, u16, u32); 9] = [
        (256, 4, w),
        (257, 4, h),
        (258, 3, bits as u32),
        (259, 3, compression as u32),
        (262, 3, 1),
        (273, 4, 8 + 2 + 9 * 12 + 4),
        (277, 3, 1),
        (278, 4, h),
        (
            279,
            4,
            if compression == 1 {
                w * h * (bits as u32 / 8)
            } else {
                64
            },
        ),
    ];
    let mut v = b"II*\0".to_vec();
    v.extend(8u32.to_le_bytes());
    v.extend((entries.len() as u16).to_le_bytes());
    for (tag, ty, val) in entries {
        v.extend(tag.to_le_bytes());
        v.extend(ty.to_le_bytes());
        v.extend(1u32.to_le_bytes());
        v.extend(val.to_le_bytes());
    }
    v.extend(0u32.to_le_bytes());
    v.extend([0u8; 64]);
    v
}

fn varint(out: &mut Vec<u8>, mut v: u32) {
    loop {
        let b = (v & 0x7f) as u8;
        v >>= 7;
        if v == 0 {
            out.push(b);
            return;
        }
        out.push(b | 0x80);
    }
}

/// The hostile files: (name, bytes). Each is tiny.
fn corpus() -> Vec<(&'static str, Vec<u8>)> {
    let mut v: Vec<(&'static str, Vec<u8>)> = Vec::new();
    // Terrain.
    let mut hgt = hgt_sample();
    hgt.resize(1000, 0);
    v.push(("N10E010.hgt", hgt));
    v.push(("tiff-8000x8000.tif", tiff_header_only(8000, 8000, 16, 1)));
    v.push((
        "tiff-8000x8000-deflate.tif",
        tiff_header_only(8000, 8000, 8, 8),
    ));
    {
        use tiff::encoder::{colortype, Compression, DeflateLevel, TiffEncoder};
        let mut out = std::io::Cursor::new(Vec::new());
        TiffEncoder::new(&mut out)
            .unwrap()
            .with_compression(Compression::Deflate(DeflateLevel::Best))
            .write_image::<colortype::Gray8>(1024, 1024, &vec![7u8; 1024 * 1024])
            .unwrap();
        v.push(("tiff-budget.tif", out.into_inner()));
    }
    v.push(("png-8000x8000.png", png_header_only(8000, 8000, 16, 0)));
    v.push(("rgba-8000x8000.png", png_header_only(8000, 8000, 8, 6)));
    {
        use image::ImageEncoder;
        let img = image::GrayImage::from_pixel(1024, 1024, image::Luma([3]));
        let mut out = std::io::Cursor::new(Vec::new());
        image::codecs::png::PngEncoder::new_with_quality(
            &mut out,
            image::codecs::png::CompressionType::Best,
            image::codecs::png::FilterType::NoFilter,
        )
        .write_image(img.as_raw(), 1024, 1024, image::ExtendedColorType::L8)
        .unwrap();
        v.push(("png-budget.png", out.into_inner()));
    }
    let rgba = rgba_png_sample();
    v.push(("dome-truncated.png", rgba[..rgba.len() / 2].to_vec()));
    // Volumes.
    v.push((
        "nrrd-bomb.nrrd",
        [
            b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4096 4096 32\nencoding: gzip\n\n"
                .to_vec(),
            gzip(&[0u8; 65536]),
        ]
        .concat(),
    ));
    v.push((
        "nrrd-budget.nrrd",
        [
            b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 256 256 64\nencoding: gzip\n\n".to_vec(),
            gzip(&vec![0u8; 256 * 256 * 64]),
        ]
        .concat(),
    ));
    v.push((
        "nrrd-devzero.nrrd",
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 64 64 64\nencoding: raw\ndata file: /dev/zero\n\n"
            .to_vec(),
    ));
    v.push((
        "raw-devzero.toml",
        b"file = \"/dev/zero\"\ndims = [64, 64, 64]\ntype = \"uint8\"\n".to_vec(),
    ));
    // Voxels.
    {
        let mut f = vox_file(&[vox_size([2, 2, 2]), vox_xyzi(&[[0, 0, 0, 1]])]);
        // MAIN's children size claims 1 MB more than the file holds.
        let children = i32::from_le_bytes(f[16..20].try_into().unwrap());
        f[16..20].copy_from_slice(&(children + (1 << 20)).to_le_bytes());
        v.push(("main-overrun.vox", f));
    }
    {
        // 30 nested groups, each listing the next level twice: 2^30 shapes.
        let mut chunks = vec![vox_size([1, 1, 1]), vox_xyzi(&[[0, 0, 0, 1]])];
        for i in 0..30 {
            chunks.push(vox_trn(2 * i, 2 * i + 1, &[]));
            chunks.push(vox_grp(2 * i + 1, &[2 * i + 2, 2 * i + 2]));
        }
        chunks.push(vox_trn(60, 61, &[("_t", "1 0 0")]));
        chunks.push(vox_shp(61, &[(0, None)]));
        v.push(("graph-bomb.vox", vox_file(&chunks)));
    }
    v.push((
        "far-apart.vox",
        vox_file(&[
            vox_size([1, 1, 1]),
            vox_xyzi(&[[0, 0, 0, 1]]),
            vox_trn(0, 1, &[]),
            vox_grp(1, &[2, 4]),
            vox_trn(2, 3, &[]),
            vox_shp(3, &[(0, None)]),
            vox_trn(4, 5, &[("_t", "4000 4000 4000")]),
            vox_shp(5, &[(0, None)]),
        ]),
    ));
    {
        let mut shp = 1i32.to_le_bytes().to_vec();
        shp.extend(vox_dict(&[]));
        shp.extend(0i32.to_le_bytes());
        v.push((
            "empty-shape.vox",
            vox_file(&[
                vox_size([1, 1, 1]),
                vox_xyzi(&[[0, 0, 0, 1]]),
                vox_trn(0, 1, &[]),
                chunk(b"nSHP", &shp, &[]),
            ]),
        ));
    }
    {
        // 16x16 columns, 4096 high, all pointing at one run of 4096 voxels.
        let mut f = relief::voxel::segment::MAGIC.to_vec();
        f.extend(1u16.to_le_bytes());
        f.extend(0u16.to_le_bytes());
        for d in [16u32, 16, 4096] {
            f.extend(d.to_le_bytes());
        }
        for i in 0..256u32 {
            f.extend([i as u8, i as u8, i as u8, 255]);
        }
        for _ in 0..256 {
            f.extend(0u32.to_le_bytes());
        }
        let mut data = Vec::new();
        varint(&mut data, 0);
        varint(&mut data, 4096);
        data.extend(vec![1u8; 4096]);
        varint(&mut data, 0);
        varint(&mut data, 0);
        f.extend((data.len() as u32).to_le_bytes());
        f.extend(data);
        v.push(("one-run.rvs", f));
    }
    // Warps.
    v.push((
        "bourke-4g.data",
        b"2\n4294967296 4294967296\n0 0 0 0 1\n".to_vec(),
    ));
    v.push(("bourke-short.data", b"2\n4000 4000\n0 0 0 0 1\n".to_vec()));
    {
        let mut f = b"PF\n65536 65536\n-1.0\n".to_vec();
        f.extend([0u8; 12]);
        v.push(("pfm-huge.pfm", f));
    }
    // Text.
    v.push((
        "scene-binary.toml",
        b"[terrain]\nsource = \"x.hgt\"\n\xff\xfe\x00\x01binary".to_vec(),
    ));
    v.push((
        "scene-syntax.toml",
        b"[terrain\nsource = \"x.hgt\"\n[camera]\nposition = [0.0, 0.0]\n".to_vec(),
    ));
    v.push((
        "display-binary.toml",
        b"[screen]\n\x89PNG\r\n\x1a\n\xff".to_vec(),
    ));
    v.push((
        "display-bad.toml",
        b"[screen]\nkind = \"dome\"\ncentre = [0.0, 0.0, 0.0]\nradius = \"three\"\n".to_vec(),
    ));
    v.push(("path-binary.csv", b"time,x,y\n\xff\xff\xff\n".to_vec()));
    v.push((
        "path-bad.csv",
        b"time,x,y,alt,heading,pitch,roll\n0,0,0,1000,0,0,0\n1,1e999,0,1000,0,0,0\n".to_vec(),
    ));
    v.push((
        "script-bad.csv",
        b"time,throttle,pitch,roll,yaw\n0,7,0,0,0\n".to_vec(),
    ));
    v.push(("eyes-bad.csv", b"0,0,0\n1,2\n".to_vec()));
    // Terrain databases: an index of 2^40 tiles behind a sound header checksum, and a file of
    // another format version.
    {
        use relief::db::format::{header_len, write_header, Extent, Header, LevelInfo};
        let count = 1u64 << 40;
        let mut h = Header {
            version: 1,
            tile: 256,
            tile_count: count,
            index_offset: 0,
            data_offset: 0,
            extent: Extent {
                lon_min: 9.0,
                lat_min: 47.0,
                lon_max: 10.0,
                lat_max: 48.0,
            },
            heights: [0.0, 1.0],
            levels: vec![
                LevelInfo {
                    per_degree: 5e7,
                    x0: 0,
                    y0: 0,
                    x1: 1,
                    y1: 1,
                    tiles: 1,
                },
                LevelInfo {
                    per_degree: 1e8,
                    x0: 0,
                    y0: 0,
                    x1: 1 << 27,
                    y1: 1 << 26,
                    tiles: count - 1,
                },
            ],
            sources: Vec::new(),
        };
        h.index_offset = header_len(&h) as u64;
        h.data_offset = h.index_offset + count * 40 + 4;
        v.push(("db-index-huge.reliefdb", write_header(&h)));
        let mut other = b"RELIEFDB".to_vec();
        other.extend(9u32.to_le_bytes());
        other.resize(160, 0);
        v.push(("db-version9.reliefdb", other));
    }
    v
}

/// Writes `tests/data/hostile/` (run: `cargo test --test hostile -- --ignored write_hostile_corpus`).
#[test]
#[ignore]
fn write_hostile_corpus() {
    let d = corpus_dir();
    std::fs::create_dir_all(&d).unwrap();
    for (name, bytes) in corpus() {
        assert!(bytes.len() <= 16 << 10, "{name} is {} bytes", bytes.len());
        std::fs::write(d.join(name), bytes).unwrap();
    }
}

#[test]
fn hostile_corpus_is_checked_in_and_small() {
    for (name, _) in corpus() {
        let p = corpus_dir().join(name);
        let len = std::fs::metadata(&p)
            .unwrap_or_else(|e| {
                panic!(
                    "{}: {e}; run the ignored test write_hostile_corpus",
                    p.display()
                )
            })
            .len();
        assert!(len <= 16 << 10, "{name}: {len} bytes");
    }
}

// ---------------------------------------------------------------------------------------------
// CLI replay

fn relief_cmd() -> Command {
    common::relief_command(&[], &[])
}

/// Runs `relief args` with the address space limited to 2 GiB (loaders that allocate what a
/// hostile header claims would abort).
fn relief_limited(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 2097152; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_relief"))
        .args(args)
        .env("NODEVICE_SELECT", "1")
        .current_dir(project_dir())
        .output()
        .expect("sh runs relief")
}

fn relief(args: &[&str]) -> Output {
    relief_cmd().args(args).output().expect("relief runs")
}

fn entries(dir: &Path) -> Vec<String> {
    match std::fs::read_dir(dir) {
        Err(_) => Vec::new(),
        Ok(rd) => {
            let mut v: Vec<String> = rd
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        }
    }
}

/// Exit status 1, exactly one `error:` line mentioning every needle, no panic or abort, and
/// nothing in `out` but `keep`.
fn assert_clean(what: &str, o: &Output, needles: &[&str], out: &Path, keep: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{what}: exit status {}\nstdout: {stdout}\nstderr: {err}",
        o.status
    );
    for bad in ["panicked", "memory allocation", "RUST_BACKTRACE", "Aborted"] {
        assert!(!err.contains(bad), "{what}: `{bad}` in stderr: {err}");
    }
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(lines.len(), 1, "{what}: one error line expected: {err}");
    let line = lines[0];
    assert!(
        !err.lines()
            .any(|l| l.starts_with(' ') || l.starts_with('|')),
        "{what}: the error spans several lines: {err}"
    );
    for n in needles {
        assert!(line.contains(n), "{what}: `{n}` not in: {line}");
    }
    let left: Vec<String> = entries(out)
        .into_iter()
        .filter(|e| !keep.contains(&e.as_str()))
        .collect();
    assert!(
        left.is_empty(),
        "{what}: left in {}: {left:?}",
        out.display()
    );
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[cfg(unix)]
#[test]
fn hostile_files_fail_cleanly_through_the_cli() {
    let dir = temp_dir("cli-corpus");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let c = |name: &str| s(&corpus_dir().join(name));
    let o = s(&out);
    let scene = |name: &str, terrain: &str, extra: &str| s(&cli_scene(&dir, name, terrain, extra));
    let good_png = dir.join("good.png");
    std::fs::write(&good_png, rgba_png_sample()).unwrap();
    let good_png = s(&good_png);
    let dome = "distortion/dome-fisheye.toml";
    let terrain_file = |f: &str| {
        format!(
            "[terrain]\nsource = \"{}\"\ncell_size = [10.0, 10.0]\n",
            c(f)
        )
    };
    let drape = |f: &str| format!("[terrain]\ndrape = \"{}\"\n{PROCEDURAL}", c(f));
    let volume = |f: &str| {
        format!(
            "[[volumes]]\nsource = \"{}\"\nposition = [300.0, 300.0, 150.0]\nvoxel_size = [1.0, 1.0, 1.0]\n",
            c(f)
        )
    };
    let voxels = |f: &str| {
        format!(
            "[[voxels]]\nfile = \"{}\"\nposition = [300.0, 300.0, 150.0]\nvoxel_size = 1.0\n",
            c(f)
        )
    };
    let out_png = s(&out.join("a.png"));
    let out_rvs = s(&out.join("a.rvs"));
    let out_pfm = s(&out.join("a.pfm"));
    #[rustfmt::skip]
    let cases: Vec<(&str, Vec<String>, Vec<&str>)> = vec![
        ("hgt truncated", vec!["render".into(), scene("hgt.toml", &terrain_file("N10E010.hgt"), ""), "--out".into(), o.clone()], vec!["N10E010.hgt", "1000 bytes", "truncated"]),
        ("tiff 8000x8000", vec!["render".into(), scene("tif.toml", &terrain_file("tiff-8000x8000.tif"), ""), "--out".into(), o.clone()], vec!["tiff-8000x8000.tif", "8000x8000", "holds only"]),
        ("tiff 8000x8000 deflate", vec!["render".into(), scene("tifz.toml", &terrain_file("tiff-8000x8000-deflate.tif"), ""), "--out".into(), o.clone()], vec!["tiff-8000x8000-deflate.tif", "8000x8000", "1032:1"]),
        ("tiff over budget", vec!["render".into(), scene("tifb.toml", &terrain_file("tiff-budget.tif"), ""), "--out".into(), o.clone(), "--memory-budget".into(), "8".into()], vec!["tiff-budget.tif", "--memory-budget"]),
        ("png 8000x8000", vec!["render".into(), scene("png.toml", &terrain_file("png-8000x8000.png"), ""), "--out".into(), o.clone()], vec!["png-8000x8000.png", "8000x8000"]),
        ("png over budget", vec!["render".into(), scene("pngb.toml", &terrain_file("png-budget.png"), ""), "--out".into(), o.clone(), "--memory-budget".into(), "8".into()], vec!["png-budget.png", "--memory-budget"]),
        ("drape TIFF 8000x8000", vec!["render".into(), scene("drapet.toml", &drape("tiff-8000x8000.tif"), ""), "--out".into(), o.clone()], vec!["tiff-8000x8000.tif", "8000x8000"]),
        ("drape 8000x8000", vec!["render".into(), scene("drape.toml", &drape("rgba-8000x8000.png"), ""), "--out".into(), o.clone()], vec!["rgba-8000x8000.png", "8000x8000"]),
        ("nrrd gzip bomb", vec!["render".into(), scene("nrrd.toml", PROCEDURAL, &volume("nrrd-bomb.nrrd")), "--out".into(), o.clone()], vec!["nrrd-bomb.nrrd", "truncated"]),
        ("nrrd over budget", vec!["render".into(), scene("nrrdb.toml", PROCEDURAL, &volume("nrrd-budget.nrrd")), "--out".into(), o.clone(), "--memory-budget".into(), "4".into()], vec!["nrrd-budget.nrrd", "--memory-budget"]),
        ("nrrd data file /dev/zero", vec!["render".into(), scene("nrrdz.toml", PROCEDURAL, &volume("nrrd-devzero.nrrd")), "--out".into(), o.clone()], vec!["/dev/zero", "not a regular file"]),
        ("raw volume /dev/zero", vec!["render".into(), scene("rawz.toml", PROCEDURAL, &volume("raw-devzero.toml")), "--out".into(), o.clone()], vec!["/dev/zero", "not a regular file"]),
        ("vox MAIN overrun (render)", vec!["render".into(), scene("vox.toml", PROCEDURAL, &voxels("main-overrun.vox")), "--out".into(), o.clone()], vec!["main-overrun.vox", "MAIN"]),
        ("vox MAIN overrun (convert)", vec!["voxels".into(), "convert".into(), c("main-overrun.vox"), out_rvs.clone()], vec!["main-overrun.vox", "MAIN"]),
        ("vox graph bomb", vec!["voxels".into(), "convert".into(), c("graph-bomb.vox"), out_rvs.clone()], vec!["graph-bomb.vox", "scene graph"]),
        ("vox far apart", vec!["voxels".into(), "convert".into(), c("far-apart.vox"), out_rvs.clone(), "--memory-budget".into(), "1024".into()], vec!["far-apart.vox", "--memory-budget"]),
        ("vox empty shape", vec!["voxels".into(), "convert".into(), c("empty-shape.vox"), out_rvs.clone()], vec!["empty-shape.vox", "no model"]),
        ("rvs one run", vec!["voxels".into(), "convert".into(), c("one-run.rvs"), out_rvs.clone()], vec!["one-run.rvs", "overlaps"]),
        ("bourke 4G nodes (inspect)", vec!["warp".into(), "inspect".into(), c("bourke-4g.data")], vec!["bourke-4g.data", "nx ny"]),
        ("bourke 4G nodes (apply)", vec!["warp".into(), "apply".into(), "--mesh".into(), c("bourke-4g.data"), "--size".into(), "32x24".into(), "--dome-master".into(), good_png.clone(), "--out".into(), out_png.clone()], vec!["bourke-4g.data", "nx ny"]),
        ("bourke short", vec!["warp".into(), "apply".into(), "--mesh".into(), c("bourke-short.data"), "--size".into(), "32x24".into(), "--dome-master".into(), good_png.clone(), "--out".into(), out_png.clone()], vec!["bourke-short.data", "16000000 nodes", "has 1"]),
        ("pfm huge", vec!["warp".into(), "inspect".into(), c("pfm-huge.pfm")], vec!["pfm-huge.pfm", "short data"]),
        ("scene binary", vec!["render".into(), c("scene-binary.toml"), "--out".into(), o.clone()], vec!["scene-binary.toml", "not a text file (invalid UTF-8 at byte 27)"]),
        ("scene syntax", vec!["render".into(), c("scene-syntax.toml"), "--out".into(), o.clone()], vec!["scene-syntax.toml", "line 1"]),
        ("display binary", vec!["warp".into(), "export".into(), c("display-binary.toml"), "--out".into(), out_pfm.clone()], vec!["display-binary.toml", "not a text file"]),
        ("display bad", vec!["warp".into(), "export".into(), c("display-bad.toml"), "--out".into(), out_pfm.clone()], vec!["display-bad.toml", "line 1", "\"three\", expected f64"]),
        ("dome master 8000x8000", vec!["warp".into(), "apply".into(), dome.into(), "--dome-master".into(), c("rgba-8000x8000.png"), "--out".into(), out_png.clone()], vec!["rgba-8000x8000.png", "8000x8000"]),
        ("dome master truncated", vec!["warp".into(), "apply".into(), dome.into(), "--dome-master".into(), c("dome-truncated.png"), "--out".into(), out_png.clone()], vec!["dome-truncated.png", "dome master"]),
        ("path csv binary", vec!["view".into(), scene("v1.toml", PROCEDURAL, ""), "--path".into(), c("path-binary.csv")], vec!["path-binary.csv", "not a text file"]),
        ("path csv bad", vec!["view".into(), scene("v2.toml", PROCEDURAL, ""), "--path".into(), c("path-bad.csv")], vec!["path-bad.csv", "line 3"]),
        ("script csv bad", vec!["view".into(), scene("v3.toml", PROCEDURAL, ""), "--mode".into(), "aircraft".into(), "--script".into(), c("script-bad.csv")], vec!["script-bad.csv", "throttle"]),
        ("db index of 2^40 tiles", vec!["db".into(), "info".into(), c("db-index-huge.reliefdb")], vec!["db-index-huge.reliefdb", "1099511627776 tiles", "holds only"]),
        ("db version 9 (render)", vec!["render".into(), scene("db9.toml", &format!("[terrain]\ndatabase = \"{}\"\n", c("db-version9.reliefdb")), ""), "--out".into(), o.clone()], vec!["db-version9.reliefdb", "format version 9"]),
        ("eye feed bad", vec!["view".into(), scene("v4.toml", PROCEDURAL, ""), "--display".into(), dome.into(), "--eye-feed".into(), c("eyes-bad.csv")], vec!["eyes-bad.csv", "line 2"]),
    ];
    for (what, args, needles) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let r = relief_limited(&args);
        assert_clean(what, &r, needles, &out, &[]);
        if what.starts_with("scene binary") {
            let err = String::from_utf8_lossy(&r.stderr);
            assert_eq!(err.matches("UTF-8").count(), 1, "printed once: {err}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn dev_zero_and_sparse_files_are_not_read_whole() {
    let dir = temp_dir("cli-sparse");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let o = s(&out);
    // /dev/zero as a tile.
    let zero = dir.join("N30E030.hgt");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    // 6 GiB sparse files: a tile, a detached NRRD data file, a raw volume.
    let big = dir.join("N31E031.hgt");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(6 << 30)
        .unwrap();
    let data = dir.join("big.raw");
    std::fs::File::create(&data)
        .unwrap()
        .set_len(6 << 30)
        .unwrap();
    let nhdr = dir.join("big.nhdr");
    std::fs::write(
        &nhdr,
        "NRRD0004\ntype: float\ndimension: 3\nsizes: 2048 2048 127\nencoding: raw\ndata file: big.raw\n\n",
    )
    .unwrap();
    let raw = dir.join("big.toml");
    std::fs::write(
        &raw,
        "file = \"big.raw\"\ndims = [2048, 2048, 127]\ntype = \"float\"\n",
    )
    .unwrap();
    let terrain = |p: &Path| format!("[terrain]\nsource = \"{}\"\n", s(p));
    let volume = |p: &Path| {
        format!(
            "[[volumes]]\nsource = \"{}\"\nposition = [300.0, 300.0, 150.0]\nvoxel_size = [1.0, 1.0, 1.0]\n",
            s(p)
        )
    };
    let cases: Vec<(&str, PathBuf, Vec<&str>, Vec<&str>)> = vec![
        (
            "/dev/zero tile",
            cli_scene(&dir, "a.toml", &terrain(&zero), ""),
            vec![],
            vec!["N30E030.hgt", "not a regular file"],
        ),
        (
            "sparse tile",
            cli_scene(&dir, "b.toml", &terrain(&big), ""),
            vec![],
            vec!["N31E031.hgt", "6442450944 bytes", "not an SRTM tile"],
        ),
        (
            "sparse NRRD data",
            cli_scene(&dir, "c.toml", PROCEDURAL, &volume(&nhdr)),
            vec!["--memory-budget", "1024"],
            vec!["big.nhdr", "--memory-budget"],
        ),
        (
            "sparse raw volume",
            cli_scene(&dir, "d.toml", PROCEDURAL, &volume(&raw)),
            vec!["--memory-budget", "1024"],
            vec!["big.toml", "--memory-budget"],
        ),
    ];
    for (what, scene, extra, needles) in cases {
        let sc = s(&scene);
        let mut args = vec!["render", sc.as_str(), "--out", o.as_str()];
        args.extend(extra);
        let t = std::time::Instant::now();
        let r = relief_limited(&args);
        assert_clean(what, &r, &needles, &out, &[]);
        assert!(t.elapsed().as_secs() < 20, "{what}: took {:?}", t.elapsed());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn outputs_that_are_directories_leave_nothing_behind() {
    let dir = temp_dir("cli-outdir");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let scene = cli_scene(&dir, "s.toml", PROCEDURAL, "");
    let (sc, o) = (s(&scene), s(&out));
    let good_png = dir.join("good.png");
    std::fs::write(&good_png, rgba_png_sample()).unwrap();
    let mesh = s(&project_dir().join("tests/data/standard_16x9.data"));
    let deer = s(&terrains().join("voxels/deer.vox"));
    for blocker in ["frame_0000.png", "depth_0000.tiff", "frame_0000.json"] {
        std::fs::create_dir(out.join(blocker)).unwrap();
        let r = relief(&["render", &sc, "--out", &o, "--size", "32x24"]);
        assert_clean(
            &format!("render with {blocker} a directory"),
            &r,
            &[blocker, "directory"],
            &out,
            &[blocker],
        );
        std::fs::remove_dir(out.join(blocker)).unwrap();
    }
    let blocked = out.join("blocked");
    std::fs::create_dir(&blocked).unwrap();
    let b = s(&blocked);
    #[rustfmt::skip]
    let cases: Vec<(&str, Vec<&str>)> = vec![
        ("warp apply", vec!["warp", "apply", "--mesh", &mesh, "--size", "32x24", "--dome-master", good_png.to_str().unwrap(), "--out", &b]),
        ("warp export", vec!["warp", "export", "distortion/dome-fisheye.toml", "--out", &b]),
        ("voxels convert", vec!["voxels", "convert", &deer, &b]),
    ];
    for (what, args) in cases {
        let r = relief(&args);
        assert_clean(what, &r, &["blocked"], &out, &["blocked"]);
    }
    // `warp verify` writes its images, then verify.json: the images stay (complete), no
    // temporary file does.
    let v = dir.join("verify");
    std::fs::create_dir_all(v.join("verify.json")).unwrap();
    let r = relief(&[
        "warp",
        "verify",
        "distortion/dome-fisheye.toml",
        "--size",
        "48x48",
        "--no-two-pass",
        "--out",
        &s(&v),
    ]);
    let keep: Vec<String> = entries(&v)
        .into_iter()
        .filter(|e| e.ends_with(".png") || e == "verify.json")
        .collect();
    let keep: Vec<&str> = keep.iter().map(String::as_str).collect();
    assert_clean("warp verify", &r, &["verify.json", "directory"], &v, &keep);
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn a_full_disk_leaves_no_partial_files() {
    let dir = temp_dir("cli-full");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let scene = cli_scene(&dir, "s.toml", PROCEDURAL, "");
    let (sc, o) = (s(&scene), s(&out));
    let mesh = s(&project_dir().join("tests/data/standard_16x9.data"));
    let tree = s(&terrains().join("voxels/tree.vox"));
    // Noise, so that the warped output does not compress below the limit.
    let mut rng = Rng::new(99);
    let noise = image::RgbaImage::from_fn(256, 256, |_, _| {
        let v = rng.next_u64().to_le_bytes();
        image::Rgba([v[0], v[1], v[2], 255])
    });
    let good_png = dir.join("noise.png");
    std::fs::write(&good_png, png_bytes(image::DynamicImage::ImageRgba8(noise))).unwrap();
    let (pfm, bourke, rvs, png) = (
        s(&out.join("w.pfm")),
        s(&out.join("w.data")),
        s(&out.join("t.rvs")),
        s(&out.join("a.png")),
    );
    #[rustfmt::skip]
    let cases: Vec<(&str, Vec<&str>)> = vec![
        ("render", vec!["render", &sc, "--out", &o, "--size", "128x96"]),
        ("warp export pfm", vec!["warp", "export", "distortion/dome-fisheye.toml", "--out", &pfm]),
        ("warp export mesh", vec!["warp", "export", "distortion/dome-fisheye.toml", "--step", "1", "--out", &bourke]),
        ("voxels convert", vec!["voxels", "convert", &tree, &rvs]),
        ("warp apply", vec!["warp", "apply", "--mesh", &mesh, "--size", "512x512", "--dome-master", good_png.to_str().unwrap(), "--out", &png]),
    ];
    for (what, args) in cases {
        // 64 blocks of 512 bytes: writing past 32 KiB fails with EFBIG (SIGXFSZ ignored).
        let r = Command::new("sh")
            .arg("-c")
            .arg("trap '' XFSZ; ulimit -f 64; exec \"$0\" \"$@\"")
            .arg(env!("CARGO_BIN_EXE_relief"))
            .args(&args)
            .env("NODEVICE_SELECT", "1")
            .current_dir(project_dir())
            .output()
            .unwrap();
        assert_clean(what, &r, &["too large"], &out, &[]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn sigint_and_sigterm_remove_unfinished_files() {
    let dir = temp_dir("cli-signal");
    let scene = cli_scene(&dir, "s.toml", PROCEDURAL, "");
    for (sig, code) in [(libc::SIGTERM, 143), (libc::SIGINT, 130)] {
        let out = dir.join(format!("out-{sig}"));
        let mut cmd = relief_cmd();
        // A test run started in the background (`cmd &` in a script) hands its children SIGINT
        // ignored, which relief keeps ignoring as it should: give the child the default
        // dispositions, as an interactive shell does.
        unsafe {
            use std::os::unix::process::CommandExt;
            cmd.pre_exec(|| {
                libc::signal(libc::SIGINT, libc::SIG_DFL);
                libc::signal(libc::SIGTERM, libc::SIG_DFL);
                Ok(())
            });
        }
        let mut child = cmd
            .args([
                "render",
                &s(&scene),
                "--out",
                &s(&out),
                "--size",
                "64x48",
                "--frames",
                "100000",
            ])
            .stderr(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let t = std::time::Instant::now();
        while !out.join("frame_0001.json").exists() {
            assert!(t.elapsed().as_secs() < 180, "no frame written");
            if let Some(st) = child.try_wait().unwrap() {
                panic!("relief exited early: {st}");
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        unsafe {
            libc::kill(child.id() as i32, sig);
        }
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(
            o.status.code(),
            Some(code),
            "signal {sig}: {}: {err}",
            o.status
        );
        let left: Vec<String> = entries(&out)
            .into_iter()
            .filter(|e| e.contains("relief-tmp") || e.contains("partial"))
            .collect();
        assert!(left.is_empty(), "signal {sig}: left {left:?}");
        // Every frame present is complete (all three files).
        let names = entries(&out);
        let frames = names.iter().filter(|n| n.ends_with(".png")).count();
        assert!(frames >= 2);
        assert_eq!(names.len(), 3 * frames, "{names:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
