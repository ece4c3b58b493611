"""Assemble a run's simulator snapshots (PNG files, sorted by name) into a video.

OpenCV's VideoWriter with the ``mp4v`` codec writes an MP4 that common players open; the
frame rate is chosen so that the video lasts about 20 s (between 2 and 25 frames per s).
"""
import glob
import os

from patrolling_sim.common.errors import PatrolInputError


def assemble_video(snapshot_dir, out_path, fps=None):
    """Write ``out_path`` from ``snapshot_dir/*.png``; return its path.

    Raises:
        PatrolInputError: no snapshots, an unreadable image, or the writer cannot open.
    """
    import cv2
    frames = sorted(glob.glob(os.path.join(snapshot_dir, "*.png")))
    if not frames:
        raise PatrolInputError(f"{snapshot_dir}: no PNG snapshots to assemble")
    first = cv2.imread(frames[0], cv2.IMREAD_COLOR)
    if first is None:
        raise PatrolInputError(f"{frames[0]}: cannot read snapshot")
    h, w = first.shape[:2]
    h2, w2 = h - h % 2, w - w % 2            # even sizes for the codec
    if fps is None:
        fps = min(25.0, max(2.0, len(frames) / 20.0))
    tmp = out_path + ".part.mp4"
    writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*"mp4v"), fps, (w2, h2))
    if not writer.isOpened():
        raise PatrolInputError(f"{out_path}: OpenCV cannot open an MP4 writer")
    try:
        for f in frames:
            img = cv2.imread(f, cv2.IMREAD_COLOR)
            if img is None:
                raise PatrolInputError(f"{f}: cannot read snapshot")
            if img.shape[:2] != (h, w):
                img = cv2.resize(img, (w, h))
            writer.write(img[:h2, :w2])
    finally:
        writer.release()
    os.replace(tmp, out_path)
    return out_path


def count_frames(path):
    """Number of frames OpenCV decodes from a video file (to check it is playable)."""
    import cv2
    cap = cv2.VideoCapture(path)
    n = 0
    while cap.isOpened():
        ok, _ = cap.read()
        if not ok:
            break
        n += 1
    cap.release()
    return n
