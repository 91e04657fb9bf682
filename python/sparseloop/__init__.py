"""sparseloop: loop closure for monocular visual SLAM (README, "Python").

    closing = sparseloop.LoopClosing(solve_while_running=False)
    event = closing.add_keyframe(id, timestamp, image_uint8, (fx, fy, cx, cy), pose_4x4)
    closing.finish(); closing.corrections()["poses"]   # (N, 4, 4) corrected poses
"""
from ._sparseloop import (  # noqa: F401
    Error,
    FileError,
    LoopClosing,
    default_config,
    evaluate_trajectory,
    presets,
    read_image,
    read_mapped_pixels,
    read_trajectory,
    write_trajectory,
)
