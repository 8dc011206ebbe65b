#!/usr/bin/python3
"""An independent Modbus server for calbox's client tests: pymodbus, 100 holding registers from
address 0, unit 1. TCP: pymodbus_server.py tcp PORT. RTU: pymodbus_server.py rtu DEVICE BAUD.
Prints 'serving' once started; runs until killed."""
import asyncio
import logging
import sys

from pymodbus.datastore import (ModbusSequentialDataBlock, ModbusServerContext,
                                ModbusSlaveContext)
from pymodbus.server import StartAsyncSerialServer, StartAsyncTcpServer
from pymodbus.transaction import ModbusRtuFramer


def main():
    # Exception responses are what the tests ask for: not worth a line each.
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    store = ModbusSlaveContext(hr=ModbusSequentialDataBlock(0, [0] * 100), zero_mode=True)
    context = ModbusServerContext(slaves={1: store}, single=False)
    print("serving", flush=True)
    if sys.argv[1] == "tcp":
        asyncio.run(StartAsyncTcpServer(context=context, address=("127.0.0.1", int(sys.argv[2]))))
    else:
        asyncio.run(StartAsyncSerialServer(context=context, framer=ModbusRtuFramer,
                                           port=sys.argv[2], baudrate=int(sys.argv[3])))


main()
