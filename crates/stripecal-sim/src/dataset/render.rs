//! Rendering a pose: the linear radiance, its exposure into gray or colour images, the
//! calibration views (board and laser images with their truth), the board alone and the
//! scan frames.

use super::*;

impl Twin {
    /// Linear radiance of a pose (for fidelity tests): `(image, scene)`.
    pub fn render_linear(
        &self,
        q_deg: &[f64],
        with_sphere: bool,
    ) -> Result<(LinearImage, ImageScene), SimError> {
        let scene = self.scene(q_deg, with_sphere)?;
        Ok((self.renderer()?.render(&scene), scene))
    }

    /// The world of `base` with colour channel `c`'s reflectances (`imaging.plate_rgb`,
    /// `imaging.ink_rgb`, swapped like the gray ones for light circles); `None` when
    /// they are the gray ones (the gray render serves the channel).
    fn channel_world(&self, base: &World, c: usize) -> Option<World> {
        let im = &self.cfg.imaging;
        let plate = im.plate_rgb.map_or(im.plate_reflectance, |v| v[c]);
        let ink = im.ink_rgb.map_or(im.circle_reflectance, |v| v[c]);
        if plate == im.plate_reflectance && ink == im.circle_reflectance {
            return None;
        }
        let (plate, circle) = if self.board.dark_circles {
            (plate, ink)
        } else {
            (ink, plate)
        };
        Some(World {
            plate_reflectance: plate,
            circle_reflectance: circle,
            ..base.clone()
        })
    }

    /// The linear images of a pose per colour channel: `lin` (the gray render) where
    /// the channel's reflectances are the gray ones, a render with its own otherwise.
    fn linear_rgb(
        &self,
        q_deg: &[f64],
        with_sphere: bool,
        lin: LinearImage,
    ) -> Result<[std::sync::Arc<LinearImage>; 3], SimError> {
        let base = if with_sphere {
            &self.scan_world
        } else {
            &self.calib_world
        };
        let base_cam = self.base_cam(q_deg)?;
        self.channel_renders(base, lin, |w| w.image_scene(&base_cam, self.laser()))
    }

    /// The linear images per colour channel of the scene `scene_of(world)`: `lin` (the
    /// gray render of `base`) where the channel's reflectances are the gray ones, a
    /// render of the channel's own world otherwise.
    pub(crate) fn channel_renders(
        &self,
        base: &World,
        lin: LinearImage,
        scene_of: impl Fn(&World) -> ImageScene,
    ) -> Result<[std::sync::Arc<LinearImage>; 3], SimError> {
        let gray = std::sync::Arc::new(lin);
        let mut out = [gray.clone(), gray.clone(), gray];
        for (c, slot) in out.iter_mut().enumerate() {
            if let Some(w) = self.channel_world(base, c) {
                *slot = std::sync::Arc::new(self.renderer()?.render(&scene_of(&w)));
            }
        }
        Ok(out)
    }

    /// The image of one exposure: gray, or with `imaging.colour` the RGB image and its
    /// BT.601 gray.
    pub(crate) fn expose(
        &self,
        lin: &LinearImage,
        rgb: Option<&[std::sync::Arc<LinearImage>; 3]>,
        exposure: Exposure,
        stream: u64,
    ) -> Result<(AnyGray, Option<AnyRgb>), SimError> {
        let im = &self.cfg.imaging;
        let seed = self.cfg.seed;
        Ok(match rgb {
            None => (
                form_image(lin, &self.camera, im, exposure, seed, stream),
                None,
            ),
            Some(l) => {
                let c = form_rgb(
                    [&l[0], &l[1], &l[2]],
                    &self.camera,
                    im,
                    exposure,
                    seed,
                    stream,
                )?;
                (c.to_gray(), Some(c))
            }
        })
    }

    /// Renders calibration view `index` at `q_deg`: board (and laser) image with truth.
    pub fn render_view(&self, q_deg: &[f64], index: usize) -> Result<ViewRender, SimError> {
        let (lin, scene) = self.render_linear(q_deg, false)?;
        if self.cfg.imaging.colour {
            return self.render_view_rgb(q_deg, index, lin, scene);
        }
        let im = &self.cfg.imaging;
        let seed = self.cfg.seed;
        let (board_image, laser_image) = if im.single_image {
            (
                form_image(
                    &lin,
                    &self.camera,
                    im,
                    Exposure::Single,
                    seed,
                    3 * index as u64,
                ),
                None,
            )
        } else {
            (
                form_image(
                    &lin,
                    &self.camera,
                    im,
                    Exposure::Board,
                    seed,
                    3 * index as u64,
                ),
                Some(form_image(
                    &lin,
                    &self.camera,
                    im,
                    Exposure::Laser,
                    seed,
                    3 * index as u64 + 1,
                )),
            )
        };
        Ok(ViewRender {
            board_image: Some(board_image),
            laser_image,
            board_rgb: None,
            laser_rgb: None,
            circles: target_truth(&scene, &self.camera, 0.0),
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }

    /// [`Self::render_view`] of colour images.
    fn render_view_rgb(
        &self,
        q_deg: &[f64],
        index: usize,
        lin: LinearImage,
        scene: ImageScene,
    ) -> Result<ViewRender, SimError> {
        let rgb = self.linear_rgb(q_deg, false, lin)?;
        let s = 3 * index as u64;
        let (board_image, board_rgb, laser_image, laser_rgb) = if self.cfg.imaging.single_image {
            let (g, c) = self.expose(&rgb[0], Some(&rgb), Exposure::Single, s)?;
            (g, c, None, None)
        } else {
            let (g, c) = self.expose(&rgb[0], Some(&rgb), Exposure::Board, s)?;
            let (lg, lc) = self.expose(&rgb[0], Some(&rgb), Exposure::Laser, s + 1)?;
            (g, c, Some(lg), lc)
        };
        Ok(ViewRender {
            board_image: Some(board_image),
            laser_image,
            board_rgb,
            laser_rgb,
            circles: target_truth(&scene, &self.camera, 0.0),
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }

    /// The calibration scene (the plate on its table, no sphere) with the laser off,
    /// seen from `T_board_cam` (the camera pose in the board frame, not through the
    /// robot): the scene of the board-only views of [`crate::views`].
    pub fn board_scene(&self, board_cam: &Iso3) -> ImageScene {
        let mut laser = self.laser();
        laser.peak = 0.0;
        self.board_world.image_scene(board_cam, laser)
    }

    /// Linear radiance of the board-only scene from `T_board_cam` (for fidelity tests):
    /// `(image, scene)`.
    pub fn render_board_linear(
        &self,
        board_cam: &Iso3,
    ) -> Result<(LinearImage, ImageScene), SimError> {
        let scene = self.board_scene(board_cam);
        Ok((self.renderer()?.render(&scene), scene))
    }

    /// A board image (board lit, laser off) from `T_board_cam`: the cheapest render of
    /// the twin (no laser: every pixel off an edge is one sample). `stream` selects the
    /// noise (the twin's seed, stream `stream`).
    pub fn render_board_image(&self, board_cam: &Iso3, stream: u64) -> Result<AnyGray, SimError> {
        let (lin, _) = self.render_board_linear(board_cam)?;
        Ok(form_image(
            &lin,
            &self.camera,
            &self.cfg.imaging,
            Exposure::Board,
            self.cfg.seed,
            stream,
        ))
    }

    /// Renders scan frame `index` at `q_deg` (stripe image only) with its truth.
    pub fn render_scan_frame(&self, q_deg: &[f64], index: usize) -> Result<ViewRender, SimError> {
        let (lin, scene) = self.render_linear(q_deg, true)?;
        let stream = 1_000_000 + index as u64;
        let (img, rgb) = if self.cfg.imaging.colour {
            let l = self.linear_rgb(q_deg, true, lin)?;
            self.expose(&l[0], Some(&l), Exposure::Laser, stream)?
        } else {
            self.expose(&lin, None, Exposure::Laser, stream)?
        };
        Ok(ViewRender {
            board_image: None,
            laser_image: Some(img),
            board_rgb: None,
            laser_rgb: rgb,
            circles: vec![],
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }
}
