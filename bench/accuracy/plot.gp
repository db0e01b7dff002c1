# RMSE against step, log-log, one panel per case and one line per integrator,
# with reference slopes 1 and 2 (docs/accuracy.md). Run by bench/accuracy/run.sh:
#   gnuplot -e "results='bench/accuracy/results.csv'; output='docs/accuracy_convergence.png'" bench/accuracy/plot.gp
if (!exists("results")) results = 'bench/accuracy/results.csv'
if (!exists("output")) output = 'docs/accuracy_convergence.png'

set terminal pngcairo size 1400,620 font "sans,11" enhanced
set output output
set datafile separator ','

cases = "smooth ct-spike"
titles = "'smooth field, smooth TF (64^3 float32)' 'chest CT, spike + jump TF (256x256x133 uint8)'"
integrators = "riemann-near riemann-mid alpha-near alpha-mid preintegrated-simple preintegrated"
colours = "#d62728 #d62728 #1f77b4 #1f77b4 #2ca02c #2ca02c"
dashes = "1 2 1 2 2 1"
points = "7 6 5 4 8 9"

set logscale xy
set xrange [0.1:5]
set xtics ("4" 4, "2" 2, "1" 1, "1/2" 0.5, "1/4" 0.25, "1/8" 0.125)
set format y "10^{%L}"
set xlabel "step (voxels)"
set ylabel "RMSE over RGB vs reference"
set grid xtics ytics mxtics mytics lc rgb "#dddddd"
set key bottom right font ",10" spacing 1.1

# rmse of case c, integrator i (NaN elsewhere: gnuplot skips the row)
pick(c, i) = (strcol(1) eq c && strcol(2) eq i) ? $4 : NaN

set multiplot layout 1,2
do for [p = 1:2] {
    c = word(cases, p)
    # the reference slopes pass above the largest and below the smallest RMSE at step 1/8
    stats results using ((strcol(1) eq c && $3 == 0.125) ? $4 : NaN) nooutput
    hi = 2.0 * STATS_max / 0.125
    lo = 0.3 * STATS_min / 0.125**2
    set title word(titles, p)
    plot for [k = 1:6] results using 3:(pick(c, word(integrators, k))) with linespoints \
             lc rgb word(colours, k) dt int(word(dashes, k)) pt int(word(points, k)) lw 2 ps 1.2 \
             title word(integrators, k), \
         hi * x with lines lc rgb "#555555" dt 3 lw 1.5 title "slope 1", \
         lo * x**2 with lines lc rgb "#555555" dt 4 lw 1.5 title "slope 2"
}
unset multiplot
