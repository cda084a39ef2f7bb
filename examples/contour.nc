( Line - arc - line contour for sicomat simulate --gcode; millimetres, feed in mm/min )
%
N10 G17 G90 G01 X0 Y0 F3000
N20 G01 X40 Y0
N30 G03 X60 Y20 I0 J20
N40 G01 X60 Y50
N50 M30
%
