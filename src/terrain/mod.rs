//! Terrain: a base plane perturbed by a height table, its loaders and its maximum pyramid.
//!
//! Coordinates: the *grid frame* has x, y in sample units (sample `(i, j)` at `(i, j)`) and z
//! in metres along the base plane's normal. [`TerrainFrame`] maps it to and from the world
//! (metres, x east, y north, z up by default).

pub mod curved;
pub mod desc;
pub mod drape_mips;
pub mod geotiff;
pub mod heightfield;
pub mod hgt;
pub mod hollow;
pub mod png16;
pub mod procedural;
pub mod pyramid;

pub use geotiff::Drape;
pub use heightfield::{GeoRef, Heightfield, SampleGrid, MAX_ABS_HEIGHT, MAX_SIDE};
pub use hollow::GroundNow;
pub use pyramid::MaxPyramid;

use crate::{Error, Result};
pub use desc::{HeightSource, TerrainDesc};
use glam::{DMat4, DVec3, DVec4};
use std::path::Path;

/// Placement of the height grid in the world: the base plane's origin (world position of
/// sample (0, 0) at height 0), its orthonormal axes and the sample spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TerrainFrame {
    pub origin: DVec3,
    /// Unit vector along grid +x.
    pub axis_x: DVec3,
    /// Unit vector along grid +y.
    pub axis_y: DVec3,
    /// Unit normal of the base plane (heights are measured along it).
    pub normal: DVec3,
    /// Metres per sample along x and y.
    pub spacing: [f64; 2],
}

impl TerrainFrame {
    /// World point → grid frame.
    pub fn world_to_grid(&self, p: DVec3) -> DVec3 {
        let d = p - self.origin;
        DVec3::new(
            d.dot(self.axis_x) / self.spacing[0],
            d.dot(self.axis_y) / self.spacing[1],
            d.dot(self.normal),
        )
    }
    /// World direction → grid frame (not renormalised: the ray parameter stays in metres).
    pub fn world_dir_to_grid(&self, d: DVec3) -> DVec3 {
        DVec3::new(
            d.dot(self.axis_x) / self.spacing[0],
            d.dot(self.axis_y) / self.spacing[1],
            d.dot(self.normal),
        )
    }
    /// Grid frame → world point.
    pub fn grid_to_world(&self, g: DVec3) -> DVec3 {
        self.origin
            + self.axis_x * (g.x * self.spacing[0])
            + self.axis_y * (g.y * self.spacing[1])
            + self.normal * g.z
    }
    /// World normal from the height gradient `(dh/dx, dh/dy)` in metres per grid unit.
    pub fn normal_from_gradient(&self, dhdx: f64, dhdy: f64) -> DVec3 {
        (self.normal
            - self.axis_x * (dhdx / self.spacing[0])
            - self.axis_y * (dhdy / self.spacing[1]))
            .normalize()
    }
    /// The affine matrix taking homogeneous world points to grid coordinates.
    pub fn grid_from_world(&self) -> DMat4 {
        let m = DMat4::from_cols(
            (self.axis_x * self.spacing[0]).extend(0.0),
            (self.axis_y * self.spacing[1]).extend(0.0),
            self.normal.extend(0.0),
            self.origin.extend(1.0),
        );
        m.inverse()
    }
    /// The affine matrix taking grid coordinates to world points.
    pub fn world_from_grid(&self) -> DMat4 {
        DMat4::from_cols(
            (self.axis_x * self.spacing[0]).extend(0.0),
            (self.axis_y * self.spacing[1]).extend(0.0),
            self.normal.extend(0.0),
            DVec4::new(self.origin.x, self.origin.y, self.origin.z, 1.0),
        )
    }
}

/// How a drape image maps onto the grid: texel = `offset + scale * grid`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrapeMapping {
    pub offset: [f64; 2],
    pub scale: [f64; 2],
}

/// A loaded, placed terrain with its pyramid.
#[derive(Clone, Debug)]
pub struct Terrain {
    /// Heights (already multiplied by the vertical scale).
    pub field: Heightfield,
    pub frame: TerrainFrame,
    pub pyramid: MaxPyramid,
    /// Lowest and highest sample.
    pub min_height: f32,
    pub max_height: f32,
    /// Optional draped colour image and its texel mapping.
    pub drape: Option<(Drape, DrapeMapping)>,
    /// Vertical side walls down to the lowest sample (and a floor there): rays that meet the
    /// grid's box below the surface stop at once, so the terrain renders as a solid block.
    /// `false` (`terrain.walls = false`): such rays pass under the surface, which is then
    /// only seen from above. Default `true`.
    pub walls: bool,
    /// The earth's curvature is applied (`terrain.curved`; needs a geographic reference):
    /// the surface drops below the eye's tangent plane by [`curved::GridCurvature::drop`].
    pub curved: bool,
    /// `Some` for a database window rendered through the paged tile pool (`[terrain] memory`,
    /// `--terrain-memory`): its samples are not held — `field.heights` and `pyramid.data` are
    /// empty, the pyramid keeps its levels' shapes, `min_height`/`max_height` come from the
    /// database's index — and heights ([`Terrain::height_at_grid`]) come from the database at
    /// full resolution through its bounded tile cache ([`hollow::Hollow`]).
    pub hollow: Option<hollow::Hollow>,
}

/// Terrains of fewer samples than this (query windows) log their making at `debug`.
const QUIET_BELOW: usize = 1 << 16;

impl Terrain {
    /// Places a height field in the world and builds its pyramid.
    pub fn new(
        mut field: Heightfield,
        frame: TerrainFrame,
        vertical_scale: f64,
    ) -> Result<Terrain> {
        check_vertical_scale(vertical_scale)?;
        for h in &mut field.heights {
            *h = scaled(*h, vertical_scale);
        }
        let (min_height, max_height) = checked_range(field.range(), vertical_scale)?;
        let t = std::time::Instant::now();
        let pyramid = MaxPyramid::build(&field);
        // A scene's terrain is worth a line; the small windows queries build (one per CIGI
        // query on a database scene) are not.
        let level = if field.width * field.height >= QUIET_BELOW {
            log::Level::Info
        } else {
            log::Level::Debug
        };
        log::log!(
            level,
            "terrain {}x{} samples, {:.2}x{:.2} m spacing, heights {min_height}..{max_height} m; pyramid of {} levels in {:.1} ms",
            field.width,
            field.height,
            field.spacing[0],
            field.spacing[1],
            pyramid.levels.len(),
            t.elapsed().as_secs_f64() * 1e3
        );
        Ok(Self::assemble(
            field,
            frame,
            pyramid,
            (min_height, max_height),
        ))
    }

    /// The terrain of `field` (heights scaled) with `pyramid` and the height range, placed by
    /// `frame` with the field's spacing; walls on, flat, no drape.
    fn assemble(
        field: Heightfield,
        frame: TerrainFrame,
        pyramid: MaxPyramid,
        (min_height, max_height): (f32, f32),
    ) -> Terrain {
        let frame = TerrainFrame {
            spacing: field.spacing,
            ..frame
        };
        Terrain {
            field,
            frame,
            pyramid,
            min_height,
            max_height,
            drape: None,
            walls: true,
            curved: false,
            hollow: None,
        }
    }

    /// Loads and places the terrain a scene describes. Relative paths are resolved from `base_dir`.
    pub fn from_desc(desc: &TerrainDesc, base_dir: &Path) -> Result<Terrain> {
        let field = match desc.height_source()? {
            HeightSource::Procedural(p) => p.generate()?,
            HeightSource::File(src) => {
                let path = base_dir.join(src);
                load_heightfield(
                    &path,
                    desc.cell_size,
                    desc.nodata,
                    desc.png_scale,
                    desc.png_offset,
                )?
            }
            HeightSource::Database {
                path,
                window,
                level,
            } => {
                let field = crate::db::window::load(&base_dir.join(path), window, level)?;
                return Self::from_database_field(desc, base_dir, field);
            }
        };
        Self::from_field(desc, base_dir, field)
    }

    /// [`Self::from_desc`] for a scene rendered through the paged tile pool: a database
    /// window is loaded hollow (its samples not held, [`hollow::Hollow`]); any other source
    /// as `from_desc` loads it (the paged renderer refuses it).
    pub fn from_desc_paged(desc: &TerrainDesc, base_dir: &Path) -> Result<Terrain> {
        match desc.height_source()? {
            HeightSource::Database {
                path,
                window,
                level,
            } => hollow::window(desc, base_dir, &base_dir.join(path), window, level),
            _ => Self::from_desc(desc, base_dir),
        }
    }

    /// A database scene's terrain (`desc` names the database) on window `spec` of the open
    /// database behind `tiles`, read through them (no file opened); `None` when `tiles` are
    /// resident only and one it needs is not in memory (they record which).
    pub fn from_window(
        desc: &TerrainDesc,
        base_dir: &Path,
        tiles: &dyn crate::db::Tiles,
        spec: &crate::db::WindowSpec,
    ) -> Result<Option<Terrain>> {
        match crate::db::window::read_from(tiles, spec)? {
            Some(field) => Self::from_database_field(desc, base_dir, field).map(Some),
            None => Ok(None),
        }
    }

    /// [`Self::from_field`] for a database window's samples (`cell_size` overrides their
    /// spacing).
    fn from_database_field(
        desc: &TerrainDesc,
        base_dir: &Path,
        mut field: Heightfield,
    ) -> Result<Terrain> {
        if let Some(cs) = desc.cell_size {
            field.spacing = cs;
        }
        Self::from_field(desc, base_dir, field)
    }

    /// The terrain of `desc` on its loaded samples: sea level, checks, frame, walls, curved,
    /// drape.
    fn from_field(desc: &TerrainDesc, base_dir: &Path, mut field: Heightfield) -> Result<Terrain> {
        if let Some(sea) = sea_level(desc)? {
            for h in &mut field.heights {
                *h = h.max(sea);
            }
        }
        check_height_range(desc, base_dir, field.range())?;
        let frame = desc_frame(desc, field.spacing)?;
        let terrain = Terrain::new(field, frame, desc.vertical_scale)?;
        Self::finish(desc, base_dir, terrain)
    }

    /// What a scene's `[terrain]` sets on a placed terrain: walls, the curved earth (by
    /// default on a database), the drape.
    fn finish(desc: &TerrainDesc, base_dir: &Path, mut terrain: Terrain) -> Result<Terrain> {
        terrain.walls = desc.walls;
        terrain.curved = desc.curved.unwrap_or(matches!(
            desc.height_source()?,
            HeightSource::Database { .. }
        ));
        if terrain.curved && terrain.field.geo.is_none() {
            return Err(Error::invalid(
                "terrain.curved",
                "the curved earth needs a georeferenced terrain (SRTM .hgt, a GeoTIFF in degrees or a database): remove `curved = true`",
            ));
        }
        if let Some(d) = &desc.drape {
            let drape = geotiff::load_drape(&base_dir.join(d))?;
            let mapping = drape_mapping(&terrain.field, &drape);
            terrain.drape = Some((drape, mapping));
        }
        Ok(terrain)
    }

    /// Cells along x and y.
    pub fn cells(&self) -> [usize; 2] {
        [self.field.width - 1, self.field.height - 1]
    }

    /// Lowest world z of the terrain surface (over the grid and its height range).
    pub fn lowest_z(&self) -> f64 {
        let [cw, ch] = self.cells();
        let mut z = f64::INFINITY;
        for gx in [0.0, cw as f64] {
            for gy in [0.0, ch as f64] {
                for h in [self.min_height as f64, self.max_height as f64] {
                    z = z.min(self.frame.grid_to_world(DVec3::new(gx, gy, h)).z);
                }
            }
        }
        z
    }

    /// The terrain surface point on the base-plane normal through `p` (for the default
    /// horizontal plane: the ground directly below or above `p`); `None` outside the grid.
    pub fn point_below(&self, p: DVec3) -> Option<DVec3> {
        let g = self.frame.world_to_grid(p);
        let h = self.height_at_grid(g.x, g.y)?;
        Some(self.frame.grid_to_world(DVec3::new(g.x, g.y, h)))
    }

    /// Height of `p` above the terrain surface along the base-plane normal (negative below
    /// ground); `None` outside the grid.
    pub fn height_above(&self, p: DVec3) -> Option<f64> {
        let g = self.frame.world_to_grid(p);
        self.height_at_grid(g.x, g.y).map(|h| g.z - h)
    }

    /// World position of a geodetic point `[lat, lon, alt]` (degrees, metres above mean sea
    /// level): its grid position through the terrain's geographic reference (longitude and
    /// latitude steps, linear: the flat placement every georeferenced terrain has), at `alt`
    /// along the base normal. `field` names the scene key in errors. Errors: a terrain without
    /// a geographic reference, non-finite values, a latitude or longitude off the grid.
    pub fn geodetic_to_world(&self, field: &str, lla: [f64; 3]) -> Result<DVec3> {
        let [lat, lon, alt] = lla;
        let Some(geo) = self.field.geo else {
            return Err(Error::invalid(
                field,
                "a geodetic position needs a georeferenced terrain (SRTM .hgt, a GeoTIFF in \
                 degrees or a database): give `position` in metres instead",
            ));
        };
        if !(lat.is_finite() && lon.is_finite() && alt.is_finite())
            || lat.abs() > 90.0
            || alt.abs() > 1.0e7
        {
            return Err(Error::invalid(
                field,
                format!("[{lat}, {lon}, {alt}] is not a position: give [latitude (-90..90), longitude (degrees), altitude (m, within ±1e7)]"),
            ));
        }
        let (gx, gy) = grid_of(&geo, lat, lon);
        let [cw, ch] = self.cells();
        if !(gx >= 0.0 && gy >= 0.0 && gx <= cw as f64 && gy <= ch as f64) {
            let (lat_a, lat_b) = (geo.lat0, geo.lat0 + ch as f64 * geo.dlat);
            let (lon_a, lon_b) = (geo.lon0, geo.lon0 + cw as f64 * geo.dlon);
            return Err(Error::invalid(
                field,
                format!(
                    "latitude {lat}, longitude {lon} is off the terrain, which covers latitude \
                     {:.6}..{:.6}, longitude {:.6}..{:.6}: move the position or widen the terrain (window)",
                    lat_a.min(lat_b), lat_a.max(lat_b), lon_a.min(lon_b), lon_a.max(lon_b)
                ),
            ));
        }
        Ok(self.frame.grid_to_world(DVec3::new(gx, gy, alt)))
    }

    /// The height above mean sea level of the terrain's surface under latitude `lat`,
    /// longitude `lon` (degrees; as rendered: sea level and vertical scale applied), `None`
    /// off the terrain or without a geographic reference (CIGI's ground clamping, on the
    /// frame's thread: a hollow terrain answers from the tiles in memory, see
    /// [`Terrain::height_now`], a coarser level's height standing in while a finer tile is
    /// read).
    pub fn ground_msl(&self, lat: f64, lon: f64) -> Option<f64> {
        let geo = self.field.geo?;
        if !(lat.is_finite() && lon.is_finite()) {
            return None;
        }
        let (gx, gy) = grid_of(&geo, lat, lon);
        self.height_now(gx, gy).map(|g| g.height)
    }

    /// Geodetic `[lat, lon, alt]` of a world position (the inverse of
    /// [`Terrain::geodetic_to_world`]); `None` without a geographic reference.
    pub fn world_to_geodetic(&self, p: DVec3) -> Option<[f64; 3]> {
        let geo = self.field.geo?;
        let g = self.frame.world_to_grid(p);
        Some([geo.lat0 + g.y * geo.dlat, geo.lon0 + g.x * geo.dlon, g.z])
    }

    /// The rigid offset that keeps an object anchored at world `anchor` on the curved surface
    /// seen with `curv` ([`Terrain::curvature`] of the eye): the drop below the eye's tangent
    /// plane there, down the base normal, and its horizontal offset from the eye rescaled to
    /// the eye's metric ([`curved::GridCurvature::metric`]); zero on a flat terrain. Objects
    /// are placed on the flat base plane (as the height samples are) and move by this each
    /// frame.
    pub fn curved_offset(&self, curv: &curved::GridCurvature, anchor: DVec3) -> DVec3 {
        if curv.is_flat() {
            return DVec3::ZERO;
        }
        let g = self.frame.world_to_grid(anchor);
        // Horizontally: the anchor's offset from the eye, in grid steps, measured in the
        // eye's metric instead of the frame's spacing.
        let [sx, sy] = self.frame.spacing;
        let (dx, dy) = (g.x - curv.eye.x, g.y - curv.eye.y);
        self.frame.axis_x * (dx * sx * (curv.metric.x - 1.0))
            + self.frame.axis_y * (dy * sy * (curv.metric.y - 1.0))
            - self.frame.normal * curv.drop(g.x, g.y)
    }

    /// [`Terrain::height_at_grid`] for a frame's thread, which must not wait for the disk:
    /// a loaded terrain's height, exact; a hollow terrain's from the tiles in memory
    /// ([`hollow::Hollow::height_now`]: exact once its tile is read in the background, a
    /// coarser level's meanwhile). `None` outside the grid, or where nothing is in memory
    /// there yet.
    pub fn height_now(&self, x: f64, y: f64) -> Option<GroundNow> {
        if !self.on_grid(x, y) {
            return None;
        }
        match &self.hollow {
            Some(h) => h.height_now(self.field.geo?, x, y),
            None => self.height_at_grid(x, y).map(|height| GroundNow {
                height,
                exact: true,
            }),
        }
    }

    /// [`Terrain::height_above`] for a frame's thread (the window's height above ground):
    /// from [`Terrain::height_now`], `None` until it is exact.
    pub fn height_above_now(&self, p: DVec3) -> Option<f64> {
        let g = self.frame.world_to_grid(p);
        let ground = self.height_now(g.x, g.y).filter(|h| h.exact)?;
        Some(g.z - ground.height)
    }

    /// Whether grid position `(x, y)` lies on the grid (edges included).
    fn on_grid(&self, x: f64, y: f64) -> bool {
        let [cw, ch] = self.cells();
        x >= 0.0 && y >= 0.0 && x <= cw as f64 && y <= ch as f64
    }

    /// Height of the bilinear surface at grid position `(x, y)`, or `None` outside the grid.
    /// A hollow terrain reads the tiles it needs that are not cached, waiting for the disk:
    /// a frame's thread asks [`Terrain::height_now`].
    pub fn height_at_grid(&self, x: f64, y: f64) -> Option<f64> {
        if !self.on_grid(x, y) {
            return None;
        }
        if let Some(h) = &self.hollow {
            return h.height_at_grid(self.field.geo?, x, y);
        }
        let [cw, ch] = self.cells();
        let i = (x.floor() as usize).min(cw - 1);
        let j = (y.floor() as usize).min(ch - 1);
        let (u, v) = (x - i as f64, y - j as f64);
        let f = &self.field;
        let (h00, h10, h01, h11) = (
            f.at(i, j) as f64,
            f.at(i + 1, j) as f64,
            f.at(i, j + 1) as f64,
            f.at(i + 1, j + 1) as f64,
        );
        Some(h00 * (1.0 - u) * (1.0 - v) + h10 * u * (1.0 - v) + h01 * (1.0 - u) * v + h11 * u * v)
    }
}

/// Grid position (x along longitude, y along latitude) of latitude `lat`, longitude `lon`
/// under `geo`, the longitude taken within 180° of the grid's first column.
fn grid_of(geo: &GeoRef, lat: f64, lon: f64) -> (f64, f64) {
    let lon = lon - 360.0 * ((lon - geo.lon0 + 180.0) / 360.0).floor();
    ((lon - geo.lon0) / geo.dlon, (lat - geo.lat0) / geo.dlat)
}

impl crate::geom::Ground for Terrain {
    fn ground_z(&self, p: DVec3) -> Option<f64> {
        self.point_below(p).map(|g| g.z)
    }
    fn geodetic_to_world(&self, field: &str, lla: [f64; 3]) -> Result<DVec3> {
        Terrain::geodetic_to_world(self, field, lla)
    }
}

/// What `[terrain]`'s `sea_level` and `vertical_scale` do to a height the file gives: raised
/// to the sea level, then times the vertical scale, as a loaded terrain's samples are. A paged
/// database's tiles go through it on their way to the GPU (`gpu::TerrainPool`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightMapping {
    pub sea_level: Option<f32>,
    pub vertical_scale: f64,
}

impl HeightMapping {
    /// Heights as the file gives them.
    pub const IDENTITY: HeightMapping = HeightMapping {
        sea_level: None,
        vertical_scale: 1.0,
    };

    /// The mapping of `desc`, its keys checked (errors naming them).
    pub fn of(desc: &TerrainDesc) -> Result<HeightMapping> {
        check_vertical_scale(desc.vertical_scale)?;
        Ok(HeightMapping {
            sea_level: sea_level(desc)?,
            vertical_scale: desc.vertical_scale,
        })
    }

    /// Whether heights pass unchanged.
    pub fn is_identity(&self) -> bool {
        self.sea_level.is_none() && self.vertical_scale == 1.0
    }

    /// A sample's height (a void, NaN, stays NaN).
    pub fn sample(&self, h: f32) -> f32 {
        if h.is_nan() {
            return h;
        }
        let h = self.sea_level.map_or(h, |sea| h.max(sea));
        scaled(h, self.vertical_scale)
    }

    /// A height asked of the terrain (a query's, in f64: the sea level clamps the interpolated
    /// height).
    pub fn height(&self, h: f64) -> f64 {
        let h = self.sea_level.map_or(h, |sea| h.max(sea as f64));
        h * self.vertical_scale
    }

    /// A cell's maximum: mapped as a sample (the mapping keeps order, so it still bounds the
    /// mapped samples under it); [`pyramid::PAD`] (no sample under it) stays PAD.
    pub fn maximum(&self, m: f32) -> f32 {
        if m <= pyramid::PAD {
            return m;
        }
        self.sample(m)
    }
}

/// `terrain.sea_level`, checked (a height within ±10 km).
fn sea_level(desc: &TerrainDesc) -> Result<Option<f32>> {
    match desc.sea_level {
        Some(sea) if !sea.is_finite() || sea.abs() > 1.0e4 => Err(Error::invalid(
            "terrain.sea_level",
            format!("must be a height within ±10000 m, got {sea}"),
        )),
        sea => Ok(sea.map(|s| s as f32)),
    }
}

/// The placement `[terrain]` gives a grid of `spacing`: origin and axes.
fn desc_frame(desc: &TerrainDesc, spacing: [f64; 2]) -> Result<TerrainFrame> {
    let (axis_x, axis_y, normal) = desc.axes()?;
    Ok(TerrainFrame {
        origin: DVec3::from(desc.origin),
        axis_x,
        axis_y,
        normal,
        spacing,
    })
}

/// `Err` naming `terrain.vertical_scale` unless it is in (0, 1000].
fn check_vertical_scale(vertical_scale: f64) -> Result<()> {
    if !vertical_scale.is_finite() || vertical_scale <= 0.0 || vertical_scale > 1000.0 {
        return Err(Error::invalid(
            "terrain.vertical_scale",
            format!("must be in (0, 1000], got {vertical_scale}"),
        ));
    }
    Ok(())
}

/// A height times the vertical scale, as a terrain stores it.
fn scaled(h: f32, vertical_scale: f64) -> f32 {
    if vertical_scale == 1.0 {
        h
    } else {
        (h as f64 * vertical_scale) as f32
    }
}

/// The scaled height range, or an error naming `terrain.vertical_scale` where it is not finite.
fn checked_range((lo, hi): (f32, f32), vertical_scale: f64) -> Result<(f32, f32)> {
    if !lo.is_finite() || !hi.is_finite() {
        return Err(Error::invalid(
            "terrain.vertical_scale",
            format!(
                "heights times the vertical scale {vertical_scale} are not finite \
                 ({lo}..{hi} m): check the height source's values and the scale"
            ),
        ));
    }
    Ok((lo, hi))
}

/// `Err` naming the scene field that made the heights (`(lo, hi)`, their range) non-finite or
/// absurd (beyond ±[`MAX_ABS_HEIGHT`]): `terrain.png_scale`/`png_offset` for PNG,
/// `terrain.procedural.height`.
fn check_height_range(desc: &TerrainDesc, base_dir: &Path, (lo, hi): (f32, f32)) -> Result<()> {
    let ok = |v: f32| v.is_finite() && (v as f64).abs() <= MAX_ABS_HEIGHT;
    if ok(lo) && ok(hi) {
        return Ok(());
    }
    let range = format!("{lo}..{hi} m");
    match desc.height_source()? {
        HeightSource::Procedural(p) => Err(Error::invalid(
            "terrain.procedural.height",
            format!(
                "{} m gives heights {range}, beyond ±{MAX_ABS_HEIGHT:e} m: give the \
                 peak-to-valley height in metres (default 2000)",
                p.height
            ),
        )),
        HeightSource::Database { path, .. } => Err(Error::format(
            base_dir.join(path),
            format!("heights {range} are beyond ±{MAX_ABS_HEIGHT:e} m: rebuild the database from sound sources"),
        )),
        HeightSource::File(src) => {
            let path = base_dir.join(src);
            let is_png = path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("png"));
            if is_png {
                Err(Error::invalid(
                    "terrain.png_scale/png_offset",
                    format!(
                        "{}: png_offset + grey level × png_scale = {} + value × {} gives heights \
                         {range}, beyond ±{MAX_ABS_HEIGHT:e} m: give png_scale in metres per grey \
                         level (e.g. 0.1) and png_offset in metres",
                        path.display(),
                        desc.png_offset,
                        desc.png_scale
                    ),
                ))
            } else {
                Err(Error::format(
                    &path,
                    format!("heights {range} are beyond ±{MAX_ABS_HEIGHT:e} m: set terrain.nodata if they mark voids"),
                ))
            }
        }
    }
}

fn drape_mapping(field: &Heightfield, drape: &Drape) -> DrapeMapping {
    match (field.geo, drape.geo) {
        (Some(t), Some(d)) => DrapeMapping {
            offset: [(t.lon0 - d.lon0) / d.dlon, (t.lat0 - d.lat0) / d.dlat],
            scale: [t.dlon / d.dlon, t.dlat / d.dlat],
        },
        _ => DrapeMapping {
            offset: [0.0, 0.0],
            scale: [
                (drape.width - 1) as f64 / (field.width - 1) as f64,
                (drape.height - 1) as f64 / (field.height - 1) as f64,
            ],
        },
    }
}

/// Loads a height file by extension: `.hgt`, `.tif`/`.tiff`, `.png`.
pub fn load_heightfield(
    path: &Path,
    cell_size: Option<[f64; 2]>,
    nodata: Option<f64>,
    png_scale: f64,
    png_offset: f64,
) -> Result<Heightfield> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let mut field = match ext.as_str() {
        "hgt" => hgt::load(path)?,
        "tif" | "tiff" => geotiff::load_heights(path, cell_size, nodata)?,
        "png" => png16::load(path, cell_size, png_scale, png_offset)?,
        _ => {
            return Err(Error::format(
                path,
                format!("unknown height file type `.{ext}`: use .hgt (SRTM), .tif/.tiff (GeoTIFF) or .png (grey 8/16-bit)"),
            ))
        }
    };
    if let Some(cs) = cell_size {
        field.spacing = cs;
    }
    Ok(field)
}
