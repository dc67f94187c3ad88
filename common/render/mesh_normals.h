/* mesh_normals.h - vertex normals for a mesh that has none, from its faces:
 * at each corner, the area-weighted average of the normals of the faces
 * around that vertex that meet the corner's face at no more than a given
 * angle (so a sphere turns smooth and a cube's edges stay sharp). */
#ifndef TESSERA_MESH_NORMALS_H
#define TESSERA_MESH_NORMALS_H

#include "obj.h"

/* Vertices with more faces than this keep their faces' own normals (bounds
 * the work, which grows with the square of a vertex's face count). */
#define MESH_NORMALS_MAX_VALENCE 256

/* Fill m->normals, m->normal_count and m->normal_indices (one normal per
 * triangle corner) from its faces, smoothing across edges whose faces meet
 * at most max_angle_deg apart. m must have no normals yet. Returns 0, or -1
 * when out of memory (m unchanged). */
int mesh_normals_from_faces(obj_mesh *m, double max_angle_deg);

#endif
