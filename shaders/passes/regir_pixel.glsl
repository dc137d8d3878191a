// The per-pixel side of the ReGIR grid that restir_initial.comp and restir_initial_temporal.comp
// share (included after their `grid_cells` binding, which it reads and writes): the pixel's cell,
// whether this frame's regir_build built it, and the cell's normalisation from its previous build;
// then the pixel asks for its cell for the next frame's build. Only the passes' `grid` variants
// (build.rs, REGIR_GRID) have a grid.
#ifndef REGIR_PIXEL_GLSL
#define REGIR_PIXEL_GLSL

GridPick regir_pixel(Surface s, GridParams g, VplParams p) {
#ifndef REGIR_GRID
    // The default variant: no grid, a compile-time constant (lavapipe would otherwise run the
    // grid's code in the candidate loops: +50 % in restir_initial, measured).
    return grid_pick(g, -1, 0.0, p);
#else
    int cell = s.offset_scale >= 0.0 && g.grid_candidates > 0u ? regir_cell(g, s.position) : -1;
    if (cell < 0) {
        return grid_pick(g, -1, 0.0, p);
    }
    uvec4 rec = grid_cells[cell];
    uint stamp = frame.frame_index + 1u;
    if (rec.x != stamp) {
        grid_cells[cell].x = stamp;  // build it next frame (every writer stores the same value)
    }
    // Built this frame: its entries are this frame's draws over the current VPLs.
    bool built = rec.y == stamp;
    return grid_pick(g, built ? cell : -1, uintBitsToFloat(rec.w), p);
#endif
}

#endif
