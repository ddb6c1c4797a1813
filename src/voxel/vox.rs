//! MagicaVoxel `.vox` import (versions 150 and 200): `SIZE`/`XYZI` models, the `RGBA`
//! palette and the scene graph (`nTRN` transforms with rotation `_r` and translation `_t`,
//! `nGRP` groups, `nSHP` shapes whose models carry animation frame keys `_f`). Other chunks
//! (materials, layers, render settings) are skipped. Every bounds violation is an error naming
//! the file and the byte offset; nothing panics on malformed input.
//!
//! Composition: each shape's voxel centres `v + ½ − ⌊size/2⌋` go through the transforms from
//! the root down (integer signed-permutation rotations, integer translations), so every voxel
//! lands on the lattice; all frames share one bounding box. Without a scene graph a file with
//! several models is an animation, one model per frame.
//!
//! Hostile files: every chunk and count is checked against the bytes that hold it, the scene
//! graph is bounded ([`MAX_PLACEMENTS`] shapes, [`MAX_GRAPH_VISITS`] node visits: groups that
//! list a child twice at each of 30 levels would place 2^30 shapes from 1 KB), and the composed
//! voxels and the models' grids are checked against the memory budget
//! ([`crate::fileio::check_alloc`]) before they are built.

use super::{Voxel, VoxelModel};
use crate::{fileio, Error, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// One `SIZE` + `XYZI` pair: size and voxels `(x, y, z, palette index)`.
#[derive(Clone, Debug)]
pub struct RawModel {
    pub size: [u32; 3],
    pub voxels: Vec<[u8; 4]>,
}

/// A scene-graph node.
#[derive(Clone, Debug)]
pub enum Node {
    /// Frame 0's rotation (a signed permutation matrix, rows) and translation.
    Transform {
        child: i32,
        rotation: [[i32; 3]; 3],
        translation: [i64; 3],
    },
    Group {
        children: Vec<i32>,
    },
    /// Models with their animation frame keys.
    Shape {
        models: Vec<(u32, u32)>,
    },
}

/// A parsed `.vox` file.
#[derive(Clone, Debug)]
pub struct VoxFile {
    pub path: PathBuf,
    pub version: u32,
    pub models: Vec<RawModel>,
    /// sRGB RGBA by palette index (entry 0 unused).
    pub palette: Vec<[u8; 4]>,
    /// Whether the file had an `RGBA` chunk (else a neutral grey ramp stands in).
    pub has_palette: bool,
    pub nodes: HashMap<i32, Node>,
}

/// Most shapes the scene graph may place (instances of `nSHP` nodes after composition).
pub const MAX_PLACEMENTS: usize = 1 << 16;
/// Most node visits while composing the scene graph.
pub const MAX_GRAPH_VISITS: usize = 1 << 20;

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    end: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    fn err(&self, msg: impl std::fmt::Display) -> Error {
        Error::format(
            self.path,
            format!("malformed .vox at byte {}: {msg}", self.pos),
        )
    }
    fn bytes(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > self.end - self.pos {
            return Err(self.err(format!(
                "{what} needs {n} bytes, only {} left (truncated file?)",
                self.end - self.pos
            )));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        let b = self.bytes(4, what)?;
        Ok(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn count(&mut self, what: &str, each: usize) -> Result<usize> {
        let n = self.i32(what)?;
        if n < 0 || (n as usize).saturating_mul(each) > self.end - self.pos {
            return Err(self.err(format!("{what} {n} does not fit the chunk")));
        }
        Ok(n as usize)
    }
    fn string(&mut self) -> Result<String> {
        let n = self.count("string length", 1)?;
        Ok(String::from_utf8_lossy(self.bytes(n, "string")?).into_owned())
    }
    fn dict(&mut self) -> Result<HashMap<String, String>> {
        let n = self.count("dictionary size", 8)?;
        let mut d = HashMap::new();
        for _ in 0..n {
            let k = self.string()?;
            let v = self.string()?;
            d.insert(k, v);
        }
        Ok(d)
    }
}

fn rotation(r: u8) -> Option<[[i32; 3]; 3]> {
    let i0 = (r & 3) as usize;
    let i1 = ((r >> 2) & 3) as usize;
    if i0 > 2 || i1 > 2 || i0 == i1 {
        return None;
    }
    let i2 = 3 - i0 - i1;
    let mut m = [[0; 3]; 3];
    for (row, (col, bit)) in [(i0, 4), (i1, 5), (i2, 6)].into_iter().enumerate() {
        m[row][col] = if r & (1 << bit) != 0 { -1 } else { 1 };
    }
    Some(m)
}

/// The `MAIN` chunk's header: skips its content and narrows the reader to its children.
fn enter_main(r: &mut Reader) -> Result<()> {
    let id = r.bytes(4, "MAIN chunk id")?;
    if id != b"MAIN" {
        return Err(r.err("the first chunk must be MAIN"));
    }
    let content = r.count("MAIN content size", 1)?;
    let children = r.count("MAIN children size", 1)?;
    if content + children > r.end - r.pos {
        return Err(r.err(format!(
            "MAIN claims {content} + {children} bytes of content and children, the file holds {} after its header (truncated file?)",
            r.end - r.pos
        )));
    }
    r.bytes(content, "MAIN content")?;
    r.end = r.pos + children;
    Ok(())
}

/// A `SIZE` chunk starting at byte `at`: the next model's size, 1..=256 per side.
fn read_size(r: &mut Reader, at: usize) -> Result<[u32; 3]> {
    let s = [r.i32("SIZE x")?, r.i32("SIZE y")?, r.i32("SIZE z")?];
    if s.iter().any(|&v| !(1..=256).contains(&v)) {
        return Err(Error::format(
            r.path,
            format!("malformed .vox at byte {at}: model size {s:?} must be 1..=256 per side"),
        ));
    }
    Ok(s.map(|v| v as u32))
}

/// An `nTRN` chunk: the node id and its transform (frame 0's `_r` and `_t`).
fn read_transform(r: &mut Reader) -> Result<(i32, Node)> {
    let node = r.i32("node id")?;
    r.dict()?;
    let child = r.i32("child id")?;
    r.i32("reserved id")?;
    r.i32("layer id")?;
    let frames = r.count("frame count", 4)?;
    let mut rot = rotation(4).expect("identity");
    let mut t = [0i64; 3];
    if frames >= 1 {
        let f = r.dict()?;
        if let Some(s) = f.get("_r") {
            rot = s
                .trim()
                .parse::<u8>()
                .ok()
                .and_then(rotation)
                .ok_or_else(|| r.err(format!("node {node}: bad rotation _r {s:?}")))?;
        }
        if let Some(s) = f.get("_t") {
            t = translation(r, node, s)?;
        }
    }
    let transform = Node::Transform {
        child,
        rotation: rot,
        translation: t,
    };
    Ok((node, transform))
}

/// An `nTRN` frame's translation `_t`: three integers of at most 2^20 in magnitude.
fn translation(r: &Reader, node: i32, s: &str) -> Result<[i64; 3]> {
    let v: Vec<i64> = s
        .split_whitespace()
        .map(|x| x.parse::<i64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| r.err(format!("node {node}: bad translation _t {s:?}")))?;
    if v.len() != 3 || v.iter().any(|x| x.abs() > 1 << 20) {
        return Err(r.err(format!("node {node}: bad translation _t {s:?}")));
    }
    Ok([v[0], v[1], v[2]])
}

/// An `nGRP` chunk: the node id and its children.
fn read_group(r: &mut Reader) -> Result<(i32, Node)> {
    let node = r.i32("node id")?;
    r.dict()?;
    let k = r.count("group child count", 4)?;
    let children = (0..k)
        .map(|_| r.i32("child id"))
        .collect::<Result<Vec<_>>>()?;
    Ok((node, Node::Group { children }))
}

/// An `nSHP` chunk: the node id and its models with their frame keys `_f`.
fn read_shape(r: &mut Reader) -> Result<(i32, Node)> {
    let node = r.i32("node id")?;
    r.dict()?;
    let k = r.count("shape model count", 8)?;
    if k == 0 {
        return Err(r.err(format!("node {node}: shape lists no model")));
    }
    let mut models = Vec::with_capacity(k);
    for i in 0..k {
        let id = r.i32("model id")?;
        let d = r.dict()?;
        let f = match d.get("_f") {
            Some(s) => s
                .trim()
                .parse::<u32>()
                .map_err(|_| r.err(format!("node {node}: bad frame _f {s:?}")))?,
            None => i as u32,
        };
        if id < 0 {
            return Err(r.err(format!("node {node}: model id {id}")));
        }
        models.push((id as u32, f));
    }
    Ok((node, Node::Shape { models }))
}

impl VoxFile {
    /// Reads and parses a `.vox` file.
    pub fn load(path: &Path) -> Result<VoxFile> {
        let data = fileio::read_file(path, fileio::memory_budget())?;
        Self::parse(&data, path)
    }

    /// Parses `.vox` bytes; `path` names the file in errors.
    pub fn parse(data: &[u8], path: &Path) -> Result<VoxFile> {
        let mut r = Reader {
            data,
            pos: 0,
            end: data.len(),
            path,
        };
        if r.bytes(4, "magic")? != b"VOX " {
            return Err(Error::format(
                path,
                "not a MagicaVoxel file: it does not start with \"VOX \"",
            ));
        }
        let version = r.i32("version")?;
        let mut out = VoxFile::empty(path, version as u32);
        enter_main(&mut r)?;
        let mut size: Option<[u32; 3]> = None;
        while r.pos < r.end {
            out.read_chunk(&mut r, &mut size)?;
        }
        out.check_models()?;
        Ok(out)
    }

    /// A file with no model yet and the neutral grey ramp as its palette.
    fn empty(path: &Path, version: u32) -> VoxFile {
        VoxFile {
            path: path.to_path_buf(),
            version,
            models: Vec::new(),
            palette: (0..256u32)
                .map(|i| {
                    let g = (40 + i * 215 / 255) as u8;
                    [g, g, g, 255]
                })
                .collect(),
            has_palette: false,
            nodes: HashMap::new(),
        }
    }

    /// One child chunk of `MAIN`: its header, then its content by kind (unknown kinds are
    /// skipped); leaves the reader after the chunk's children.
    fn read_chunk(&mut self, r: &mut Reader, size: &mut Option<[u32; 3]>) -> Result<()> {
        let at = r.pos;
        let id: [u8; 4] = r.bytes(4, "chunk id")?.try_into().expect("4 bytes");
        let n = r.count("chunk content size", 1)?;
        let m = r.count("chunk children size", 1)?;
        if n + m > r.end - r.pos {
            return Err(r.err("chunk runs past its parent"));
        }
        let next = r.pos + n + m;
        let parent_end = r.end;
        r.end = r.pos + n;
        match &id {
            b"SIZE" => *size = Some(read_size(r, at)?),
            b"XYZI" => {
                let s = size
                    .take()
                    .ok_or_else(|| r.err("XYZI without a SIZE before it"))?;
                self.read_xyzi(r, s)?;
            }
            b"RGBA" => self.read_rgba(r)?,
            b"nTRN" => {
                let (node, transform) = read_transform(r)?;
                self.nodes.insert(node, transform);
            }
            b"nGRP" => {
                let (node, group) = read_group(r)?;
                self.nodes.insert(node, group);
            }
            b"nSHP" => {
                let (node, shape) = read_shape(r)?;
                self.nodes.insert(node, shape);
            }
            _ => {}
        }
        r.end = parent_end;
        r.pos = next;
        Ok(())
    }

    /// An `XYZI` chunk: the voxels of the model whose `SIZE` came before it.
    fn read_xyzi(&mut self, r: &mut Reader, s: [u32; 3]) -> Result<()> {
        let k = r.count("voxel count", 4)?;
        let raw = r.bytes(4 * k, "voxels")?;
        let mut voxels = Vec::with_capacity(k);
        for v in raw.chunks_exact(4) {
            if (0..3).any(|a| v[a] as u32 >= s[a]) || v[3] == 0 {
                return Err(Error::format(
                    r.path,
                    format!(
                        "malformed .vox: model {} has voxel {:?} outside its {}x{}x{} size or with colour index 0",
                        self.models.len(),
                        &v[..3],
                        s[0],
                        s[1],
                        s[2]
                    ),
                ));
            }
            voxels.push([v[0], v[1], v[2], v[3]]);
        }
        self.models.push(RawModel { size: s, voxels });
        Ok(())
    }

    /// An `RGBA` chunk: the palette.
    fn read_rgba(&mut self, r: &mut Reader) -> Result<()> {
        let p = r.bytes(1024, "RGBA palette")?;
        // Entry i of the chunk is the colour of index i + 1.
        for i in 1..256 {
            self.palette[i].copy_from_slice(&p[4 * (i - 1)..4 * i]);
        }
        self.has_palette = true;
        Ok(())
    }

    /// The final check: at least one model, and every shape names a model of the file.
    fn check_models(&self) -> Result<()> {
        if self.models.is_empty() {
            return Err(Error::format(
                &self.path,
                "the .vox file holds no model (no XYZI chunk)",
            ));
        }
        for n in self.nodes.values() {
            if let Node::Shape { models } = n {
                if let Some((id, _)) = models
                    .iter()
                    .find(|(id, _)| *id as usize >= self.models.len())
                {
                    return Err(Error::format(
                        &self.path,
                        format!(
                            "malformed .vox: a shape names model {id}, the file has {}",
                            self.models.len()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Voxels per model, in file order.
    pub fn model_voxel_counts(&self) -> Vec<usize> {
        self.models.iter().map(|m| m.voxels.len()).collect()
    }

    /// Shapes placed by the scene graph: (models with frame keys, rotation, translation).
    fn placements(&self) -> Result<Vec<Placement>> {
        let mut out = Vec::new();
        let ident = rotation(4).expect("identity");
        // (node, rotation, translation, depth)
        let mut stack = vec![(0i32, ident, [0i64; 3], 0u32)];
        let mut visits = 0usize;
        while let Some((id, rot, t, depth)) = stack.pop() {
            visits += 1;
            if visits > MAX_GRAPH_VISITS || out.len() > MAX_PLACEMENTS {
                return Err(Error::Limit {
                    what: format!("{} scene graph (nTRN/nGRP/nSHP)", self.path.display()),
                    msg: format!(
                        "it places more than {MAX_PLACEMENTS} shapes or visits more than {MAX_GRAPH_VISITS} nodes (groups listing the same child over and over?)"
                    ),
                });
            }
            if depth > 256 {
                return Err(Error::format(
                    &self.path,
                    "malformed .vox: the scene graph nests deeper than 256 (a cycle?)",
                ));
            }
            let node = self.nodes.get(&id).ok_or_else(|| {
                Error::format(
                    &self.path,
                    format!("malformed .vox: the scene graph names node {id}, which is missing"),
                )
            })?;
            match node {
                Node::Transform {
                    child,
                    rotation: r,
                    translation: tr,
                } => {
                    // parent ∘ (r, tr): p -> rot (r p + tr) + t
                    let mut m = [[0; 3]; 3];
                    let mut nt = t;
                    for i in 0..3 {
                        for j in 0..3 {
                            m[i][j] = (0..3).map(|k| rot[i][k] * r[k][j]).sum();
                        }
                        nt[i] += (0..3).map(|k| rot[i][k] as i64 * tr[k]).sum::<i64>();
                    }
                    stack.push((*child, m, nt, depth + 1));
                }
                Node::Group { children } => {
                    for c in children.iter().rev() {
                        stack.push((*c, rot, t, depth + 1));
                    }
                }
                Node::Shape { models } => out.push((models.clone(), rot, t)),
            }
        }
        Ok(out)
    }

    /// The file's animation frames as models sharing one box (one frame for a still file).
    pub fn frames(&self) -> Result<Vec<VoxelModel>> {
        if self.nodes.is_empty() {
            return self.model_frames();
        }
        let shapes = self.placements()?;
        let frames = shapes
            .iter()
            .flat_map(|(ms, _, _)| ms.iter().map(|(_, f)| f.saturating_add(1)))
            .max()
            .unwrap_or(1)
            .min(1024);
        // Each shape's models sorted by frame key.
        let sorted: Vec<Vec<(u32, u32)>> = shapes
            .iter()
            .map(|(ms, _, _)| {
                let mut s = ms.clone();
                s.sort_by_key(|(_, f)| *f);
                s
            })
            .collect();
        self.check_composed(&sorted, frames as usize)?;
        let cells = self.compose(&shapes, &sorted, frames as usize);
        self.frames_from_cells(cells)
    }

    /// Without a scene graph: one frame per model, each in its own box.
    fn model_frames(&self) -> Result<Vec<VoxelModel>> {
        let what = self.path.display().to_string();
        let grids = self.models.iter().fold(0u64, |acc, m| {
            acc.saturating_add(super::model_memory(m.size, m.voxels.len() as u64))
        });
        fileio::check_alloc(
            format!("{} ({} model(s))", self.path.display(), self.models.len()),
            grids,
        )?;
        self.models
            .iter()
            .map(|m| {
                let voxels = m
                    .voxels
                    .iter()
                    .map(|v| Voxel {
                        pos: [v[0] as u32, v[1] as u32, v[2] as u32],
                        index: v[3],
                    })
                    .collect();
                VoxelModel::new(&what, m.size, self.palette.clone(), voxels)
            })
            .collect()
    }

    /// The composed voxels of all frames, counted against the memory budget before they are
    /// built.
    fn check_composed(&self, sorted: &[Vec<(u32, u32)>], frames: usize) -> Result<()> {
        let mut total: u64 = 0;
        for k in 0..frames {
            for s in sorted {
                if let Some(id) = shown_model(s, k) {
                    total += self.models[id as usize].voxels.len() as u64;
                }
            }
            // World cell + voxel + the model's sort: about 64 bytes per composed voxel.
            fileio::check_alloc(
                format!("{} (composed scene graph)", self.path.display()),
                total.saturating_mul(64),
            )?;
        }
        Ok(())
    }

    /// World cells (lattice position, palette index) per frame: each placed shape's model
    /// shown at that frame, its voxel centres rotated and translated.
    fn compose(
        &self,
        shapes: &[Placement],
        sorted: &[Vec<(u32, u32)>],
        frames: usize,
    ) -> Vec<Vec<([i64; 3], u8)>> {
        let mut cells: Vec<Vec<([i64; 3], u8)>> = vec![Vec::new(); frames];
        for (k, cell) in cells.iter_mut().enumerate() {
            for ((_, rot, t), s) in shapes.iter().zip(sorted) {
                let Some(id) = shown_model(s, k) else {
                    continue;
                };
                let m = &self.models[id as usize];
                let half = m.size.map(|s| (s / 2) as i64);
                for v in &m.voxels {
                    // Twice the centre, v + ½ − ⌊s/2⌋, so everything stays integer.
                    let c2 = [0, 1, 2].map(|a| 2 * (v[a] as i64 - half[a]) + 1);
                    let w = [0, 1, 2].map(|i| {
                        let r: i64 = (0..3).map(|j| rot[i][j] as i64 * c2[j]).sum();
                        (r - 1).div_euclid(2) + t[i]
                    });
                    cell.push((w, v[3]));
                }
            }
        }
        cells
    }

    /// The frames' models in the cells' shared bounding box, checked against the size limits
    /// and the memory budget.
    fn frames_from_cells(&self, cells: Vec<Vec<([i64; 3], u8)>>) -> Result<Vec<VoxelModel>> {
        let what = self.path.display().to_string();
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        for (p, _) in cells.iter().flatten() {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        if lo[0] > hi[0] {
            return Err(Error::format(&self.path, "the scene graph places no voxel"));
        }
        let dims = [0, 1, 2].map(|a| (hi[a] - lo[a] + 1).min(u32::MAX as i64) as u32);
        super::check_dims(&what, dims)?;
        let grids = cells.iter().fold(0u64, |acc, c| {
            acc.saturating_add(super::model_memory(dims, c.len() as u64))
        });
        fileio::check_alloc(
            format!(
                "{} ({} frame(s) of {}x{}x{} voxels)",
                self.path.display(),
                cells.len(),
                dims[0],
                dims[1],
                dims[2]
            ),
            grids,
        )?;
        cells
            .into_iter()
            .map(|c| {
                let voxels = c
                    .into_iter()
                    .map(|(p, index)| Voxel {
                        pos: [0, 1, 2].map(|a| (p[a] - lo[a]) as u32),
                        index,
                    })
                    .collect();
                VoxelModel::new(&what, dims, self.palette.clone(), voxels)
            })
            .collect()
    }
}

/// A shape placed by the scene graph: (models with frame keys, rotation, translation).
type Placement = (Vec<(u32, u32)>, [[i32; 3]; 3], [i64; 3]);

/// The model a shape shows at frame `k`, from its models sorted by frame key: the last whose
/// key is ≤ k (else the first).
fn shown_model(s: &[(u32, u32)], k: usize) -> Option<u32> {
    s.iter()
        .rev()
        .find(|(_, f)| *f as usize <= k)
        .or(s.first())
        .map(|m| m.0)
}
