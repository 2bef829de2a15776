"""Stereo datasets as :class:`Scene` objects: Middlebury, KITTI (stereo and object + LiDAR), DrivingStereo, OAK-D.

Every loader returns the pair as read (BGR uint8), the ground truth in the project's convention
(float32 disparity in pixels, NaN where unknown; sparse depth in metres, NaN where no measurement),
the non-occluded mask when the dataset has one, and the :class:`calib.RectifiedRig` when the dataset
says how the pair was taken. The scale factors of the files are undone by the readers of
:mod:`stereo_classic.io`.

Layouts (one loader each; :func:`load_scene` and :func:`iter_scenes` pick the right one):

============================  ==================================================================
layout                        files
============================  ==================================================================
Middlebury 2014 / MiddEval3   ``im0.png im1.png disp0GT.pfm|disp0.pfm mask0nocc.png calib.txt``
                              (``trainingQ/H/F/<Scene>``); PFM ``inf`` -> NaN; mask 255 = non-occluded
Middlebury 2001               ``im3 im4 disp3.pgm`` (Tsukuba, x16); ``im2 im6 disp2.pgm`` (Venus,
                              Sawtooth, ..., x8)
Middlebury 2003               ``im2 im6 disp2.png`` (Cones, Teddy quarter size, x4)
Middlebury 2005 / 2006        ``view1 view5 disp1.png`` (x1, see :func:`load_middlebury_classic`)
named pair (Adirondack)       ``<Name>_left.png <Name>_right.png <Name>_gt.png <Name>_mask.png``
KITTI 2012 / 2015 stereo      ``image_2 image_3 disp_occ_0 disp_noc_0 calib_cam_to_cam/`` (2015) or
                              ``colored_0 colored_1 disp_occ disp_noc calib/`` (2012); frames
                              ``<id>_10.png``; disparity x256, 0 unknown
KITTI object + LiDAR          ``training/{image_2,image_3,calib,velodyne}/<id>`` or one folder with
                              ``left.png right.png calib.txt lidar.bin``
DrivingStereo                 ``train-{left-image,right-image,disparity-map,depth-map}/<seq>/<frame>``
                              and ``half-image-calib/<seq>.txt``; disparity and depth x256, 0 unknown
OAK-D (stereodemo)            ``<name>_left.png <name>_right.png stereodemo_calibration.json``
============================  ==================================================================

Modules: :mod:`~stereo_classic.datasets.scene` (:class:`Scene`), one per dataset family
(``middlebury``, ``kitti``, ``drivingstereo``, ``oakd``, ``demo``), ``kitti_labels`` (KITTI 3D object labels and the
LiDAR points inside each box) and
:mod:`~stereo_classic.datasets.discovery` (:func:`load_scene`, :func:`iter_scenes`).

Example
-------
>>> from stereo_classic.datasets import demo_scene
>>> scene = demo_scene()
>>> scene.left.shape, scene.gt_disparity.dtype, round(scene.rig.baseline_m, 6)
((500, 741, 3), dtype('float32'), 0.193001)
"""

from __future__ import annotations

from stereo_classic.datasets.demo import (
    DEMO_BASELINE_M,
    DEMO_CX_LEFT_PX,
    DEMO_CY_PX,
    DEMO_DOFFS_PX,
    DEMO_FOCAL_PX,
    demo_scene,
)
from stereo_classic.datasets.discovery import iter_scene_refs, iter_scenes, load_scene
from stereo_classic.datasets.drivingstereo import iter_drivingstereo, load_drivingstereo
from stereo_classic.datasets.kitti import (
    iter_kitti_object,
    iter_kitti_stereo,
    load_kitti_lidar_folder,
    load_kitti_object,
    load_kitti_stereo,
    project_lidar,
    read_kitti_calib_file,
    read_velodyne,
)
from stereo_classic.datasets.kitti_labels import (
    KittiLabel,
    KittiLabelError,
    box_corners,
    lidar_points_in_labels,
    points_in_box,
    read_kitti_labels,
    velodyne_to_rect,
)
from stereo_classic.datasets.middlebury import load_middlebury2014, load_middlebury_classic, load_named_pair
from stereo_classic.datasets.oakd import iter_oakd, load_oakd
from stereo_classic.datasets.scene import Scene, SceneRef

__all__ = [
    "Scene",
    "SceneRef",
    "load_scene",
    "iter_scenes",
    "iter_scene_refs",
    "demo_scene",
    "DEMO_FOCAL_PX",
    "DEMO_BASELINE_M",
    "DEMO_DOFFS_PX",
    "DEMO_CX_LEFT_PX",
    "DEMO_CY_PX",
    "load_middlebury2014",
    "load_middlebury_classic",
    "load_named_pair",
    "load_kitti_stereo",
    "iter_kitti_stereo",
    "load_kitti_object",
    "iter_kitti_object",
    "load_kitti_lidar_folder",
    "load_drivingstereo",
    "iter_drivingstereo",
    "load_oakd",
    "iter_oakd",
    "project_lidar",
    "read_kitti_calib_file",
    "read_velodyne",
    "KittiLabel",
    "KittiLabelError",
    "read_kitti_labels",
    "box_corners",
    "points_in_box",
    "velodyne_to_rect",
    "lidar_points_in_labels",
]
