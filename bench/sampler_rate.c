/* sampler_rate.c - how fast the Sobol sampler's error falls with the sample
 * count on one pair of dimensions (issue 15: is Tessera's sampler the reason
 * its error per sample falls more slowly than Cycles'?). For n = 16 ... 4096
 * samples in each of 4096 pixels, the MSE of the mean of a discontinuous 2D
 * integrand (a disk's indicator; the best rate for stratified points is
 * n^-1.5) and of a smooth one (a Gaussian; Owen-scrambled nets reach
 * n^-3), on pairs 1 and 4 of common/render/sampler.h. Prints MSE x n^1.5
 * and MSE x n^2: a column that stays flat falls at that rate, one that
 * shrinks falls faster.
 *
 *   cc -O2 -iquote common -iquote common/render bench/sampler_rate.c -o /tmp/sampler_rate -lm && /tmp/sampler_rate
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "render/sampler.h"

static double f_disk(double x, double y) { return (x - 0.4) * (x - 0.4) + (y - 0.55) * (y - 0.55) < 0.1 ? 1 : 0; }
static double f_smooth(double x, double y) { return exp(-8 * ((x - 0.3) * (x - 0.3) + (y - 0.6) * (y - 0.6))); }

int main(void) {
    const double disk = M_PI * 0.1; /* the disk lies inside the square */
    double smooth = 0;
    const int m = 2000;
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++) smooth += f_smooth((i + 0.5) / m, (j + 0.5) / m);
    smooth /= (double)m * m;
    const int pixels = 4096;
    for (uint32_t pair = 1; pair <= 4; pair += 3)
            for (int n = 16; n <= 4096; n *= 4) {
                double e_disk = 0, e_smooth = 0;
                for (int p = 0; p < pixels; p++) {
                    double sd = 0, ss = 0;
                    for (int k = 0; k < n; k++) {
                        sampler_stream s = sampler_start(SAMPLER_SOBOL, 1, (uint64_t)p, (uint32_t)k);
                        float u, v;
                        sampler_get_2d(&s, 2 * pair, &u, &v);
                        sd += f_disk(u, v), ss += f_smooth(u, v);
                    }
                    e_disk += (sd / n - disk) * (sd / n - disk), e_smooth += (ss / n - smooth) * (ss / n - smooth);
                }
                e_disk /= pixels, e_smooth /= pixels;
                printf("pair %u n %5d  disk MSE %.3e  x n^1.5 %.3f   smooth MSE %.3e  x n^2 %.4f\n", pair, n, e_disk,
                       e_disk * pow(n, 1.5), e_smooth, e_smooth * (double)n * n);
            }
    return 0;
}
