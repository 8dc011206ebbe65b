; Five holes in a 200 x 150 mm sheet, 15 mm in from its corners and one in the middle, around
; G54's zero at the sheet's front-left corner (examples/router_stock.toml places it with the
; camera: calbox compensate --work-zero camera).
G21 G90 G54
G0 Z5
M3 S12000
G0 X15 Y15
G1 Z-2 F300
G0 Z5
G0 X185 Y15
G1 Z-2 F300
G0 Z5
G0 X185 Y135
G1 Z-2 F300
G0 Z5
G0 X15 Y135
G1 Z-2 F300
G0 Z5
G0 X100 Y75
G1 Z-2 F300
G0 Z5
M5
M2
