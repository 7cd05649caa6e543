/* Exact CCD oracle over the rationals (GMP): decides whether a vertex–face or edge–edge pair on
 * linear trajectories touches for some t in [0, 1]. Used by the tests only. */
#ifndef WEFT_TEST_CCD_ORACLE_H
#define WEFT_TEST_CCD_ORACLE_H

#include <stdbool.h>

/* points: 8 xyz triplets as in weft_ccd_vertex_face / weft_ccd_edge_edge (all finite). */
bool oracle_vf(const double points[24]);
bool oracle_ee(const double points[24]);

#endif
