"""pyserial URL handlers of robocli (pyserial's ``protocol_handler_packages`` mechanism):
``robocli://HOST[:PORT]/PATH?baudrate=...`` is the serial port PATH of the hub at HOST,
streamed (:mod:`.protocol_robocli`). :func:`robocli.devices.hub.serial_url.register` adds this
package to pyserial's list."""
