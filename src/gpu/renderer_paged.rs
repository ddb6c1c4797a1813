//! Paged mode of [`TerrainRenderer`]: the terrain read from the tile pool
//! ([`TerrainPool`], group 3) instead of the heights and pyramid, which are not uploaded.
//! The cast pass is `shaders::cast_paged` (the paged stop rule), the shade pass reads its
//! normals from the finest resident surface and casts its shadow rays through the same paged
//! traversal; the tile pre-pass (which reads the pyramid) is off. The window's `Terrain` gives
//! the box, placement and pyramid shape only: it may be hollow (`Terrain::is_hollow`, no
//! samples held), as `World::load_as(scene, true)` makes it.

use super::super::terrain_passes::TerrainPasses;
use super::super::terrain_pool::TerrainPool;
use super::super::Gpu;
use super::TerrainRenderer;
use crate::db::pager::{PageTable, Upload};
use crate::terrain::Terrain;
use crate::{Error, Result};

impl TerrainRenderer {
    /// A renderer of the window `terrain` (a window of the database's finest level whose sample
    /// (0, 0) is sample `origin` of that level) through `pool`. Errors where the origin is not
    /// on a tile's corner (`cpu::paged::check_origin`, `PagedTerrain::new`'s rule) or the
    /// terrain has walls off (the paged traversal is walls-on only). The traversal starts at
    /// [`TerrainPool::traversal_top`].
    pub fn new_paged(
        gpu: &Gpu,
        terrain: &Terrain,
        mut pool: TerrainPool,
        origin: [i64; 2],
    ) -> Result<TerrainRenderer> {
        crate::cpu::paged::check_origin(origin, pool.tile_cells(), terrain.pyramid.top())?;
        if !terrain.walls {
            return Err(Error::invalid(
                "terrain.walls",
                "a paged terrain renders with walls on (the paged traversal has no walls-off mode)",
            ));
        }
        pool.set_window(
            gpu,
            [origin[0] as u32, origin[1] as u32],
            terrain.pyramid.top() as u32,
        );
        let kernels = gpu.options.kernels.path(&gpu.info);
        let mut r = Self::with_passes(TerrainPasses::new(
            gpu,
            terrain,
            kernels,
            Some((&pool.bgl, pool.bindings())),
        )?)?;
        r.paged = Some(pool);
        Ok(r)
    }

    /// Moves a paged renderer's window to `terrain` (a window of the same size of the same
    /// level whose sample (0, 0) is sample `origin` of it): the pool keeps its tiles, its
    /// residency map is made again for the new window. Errors as [`Self::new_paged`], and
    /// where the renderer is not paged or the window's size differs.
    pub fn set_paged_window(
        &mut self,
        gpu: &Gpu,
        terrain: &Terrain,
        origin: [i64; 2],
    ) -> Result<()> {
        let Some(pool) = &mut self.paged else {
            return Err(Error::invalid(
                "terrain.window",
                "moving the window applies to a paged renderer (--terrain-memory)",
            ));
        };
        crate::cpu::paged::check_origin(origin, pool.tile_cells(), terrain.pyramid.top())?;
        if terrain.cells() != self.base.data.cells || terrain.drape.is_some() {
            return Err(Error::invalid(
                "terrain.window",
                format!(
                    "a moved window keeps its size ({:?} cells, not {:?}) and has no drape",
                    self.base.data.cells,
                    terrain.cells()
                ),
            ));
        }
        pool.set_window(
            gpu,
            [origin[0] as u32, origin[1] as u32],
            terrain.pyramid.top() as u32,
        );
        self.lowered_for = None;
        Ok(())
    }

    /// Whether the terrain is read from a tile pool.
    pub fn is_paged(&self) -> bool {
        self.paged.is_some()
    }

    /// The tile pool of a paged renderer.
    pub fn pool(&self) -> Option<&TerrainPool> {
        self.paged.as_ref()
    }

    /// Copies a frame's uploads into the pool and the page table as it now stands
    /// ([`TerrainPool::apply`]); nothing without a pool. Queue writes only: never blocks.
    pub fn apply_pages(&mut self, gpu: &Gpu, uploads: &[Upload], table: &PageTable) {
        if let Some(p) = &mut self.paged {
            p.apply(gpu, uploads, table);
        }
    }
}
