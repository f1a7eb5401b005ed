"""Whether a render's pixels fit in memory, checked before anything is
allocated: an absurd resolution (65536 x 65536 is 4.3 gigapixels) must be a
clear error, not an allocation failure or the system's out-of-memory killer."""

import os

# Per pixel of the rendered region: the core's film (film.h: sum and
# odd-sample half sum, 2 x 12 bytes; sum of squares, 8; brightest sample and
# its index, 16; sample count, replicate slot and adaptive flag, 9; emitter
# antialiasing's statistics and extra camera rays, 21: 78), the RGBA float
# copy handed to Python (16), the numpy buffer written into Blender's result
# (16) and Blender's own Combined pass (16), rounded up for the display and
# file buffers Blender makes from it.
BYTES_PER_PIXEL = 136
# Each further pass: its film buffer, its copy and Blender's pass.
BYTES_PER_EXTRA_PASS = 48


def available_bytes():
    """Memory the system can give without swapping, or None where unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def render_memory_error(width, height, region_width, region_height, extra_passes=0, available=None):
    """The error message when the region's pixels cannot fit in memory, else None."""
    need = region_width * region_height * (BYTES_PER_PIXEL + BYTES_PER_EXTRA_PASS * extra_passes)
    if available is None:
        available = available_bytes()
    if available is None or need <= available:
        return None
    size = f"{width}x{height}"
    if (region_width, region_height) != (width, height):
        size += f" (region {region_width}x{region_height})"
    return (f"Tessera: the {size} render needs about {need / 2**30:.1f} GiB for its pixels, more than the "
            f"{available / 2**30:.1f} GiB of memory available. Lower the resolution or its percentage "
            f"(Output Properties > Format), or render the frame in parts with a render region (docs/FARM.md).")
