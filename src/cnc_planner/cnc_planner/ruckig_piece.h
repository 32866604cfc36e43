/* One degree of freedom of a ruckig trajectory, evaluated as ruckig's at_time does: the
 * row layout of jerk_profile.TrajectorySampler.rows and its evaluation, shared by the
 * kernels that sample ruckig pieces (motion/_sample_kernel.c, kinds/thread/_stock_kernel.c).
 * Built with -ffp-contract=off (setup.py), so the values equal numpy's. */
#ifndef CNC_PLANNER_RUCKIG_PIECE_H
#define CNC_PLANNER_RUCKIG_PIECE_H

/* The row layout (jerk_profile.py): t_sum (7), start (8), p, v, a, j (8 each), the
 * duration, the brake's duration and second phase's start, its p, v, a, j (2 each). */
enum { START = 7, PVAJ = 15, DURATION = 47, BRAKE = 48, BRAKE_T0 = 49, BRAKE_PVAJ = 50, ROW = 58 };

/* One instant at local time t (s from the piece's start) of the dof whose row is r. */
static inline void evaluate(const double *r, double t, double *p, double *v, double *a)
{
    const double brake = r[BRAKE];
    const int braked = brake > 0;
    const double local = braked ? t - brake : t;
    int index = 0;
    for (int k = 0; k < START; k++)
        index += local >= r[k];
    const int after = t >= r[DURATION];
    if (after)
        index = 7;
    double dt = local - r[START + index];
    double p0 = r[PVAJ + index], v0 = r[PVAJ + 8 + index], a0 = r[PVAJ + 16 + index], j = r[PVAJ + 24 + index];
    if (braked) {
        if (after) {  /* from the final state */
            dt = t - (brake + r[START - 1]);
        } else if (t < brake) {
            const int second = t >= r[BRAKE_T0];
            dt = t - (second ? r[BRAKE_T0] : 0.0);
            p0 = r[BRAKE_PVAJ + second];
            v0 = r[BRAKE_PVAJ + 2 + second];
            a0 = r[BRAKE_PVAJ + 4 + second];
            j = r[BRAKE_PVAJ + 6 + second];
        }
    }
    const double tj = dt * j;
    *a = a0 + tj;
    *v = v0 + dt * (a0 + tj / 2);
    *p = p0 + dt * (v0 + dt * (a0 / 2 + tj / 6));
}

/* As evaluate, at local time t held at the piece's end (np.minimum(t, duration)) if held. */
static inline void evaluate_held(const double *r, double t, int held, double *p, double *v, double *a)
{
    if (held && t > r[DURATION])
        t = r[DURATION];
    evaluate(r, t, p, v, a);
}

#endif
